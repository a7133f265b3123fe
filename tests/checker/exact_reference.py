"""Independent exact references for the certification tests: dense Fraction arithmetic.

Shares no code with the checker: the qualitative sets by a dense boolean fixpoint,
the values by Gauss-Jordan elimination over :class:`fractions.Fraction` on the
float64 entries taken as exact dyadic rationals.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import scipy.sparse as sp


def exact_rows(P: sp.csr_matrix, implied_loops: bool = False) -> list[dict[int, Fraction]]:
    """The float64 matrix as exact rational rows.

    :param implied_loops: read each self-loop as 1 - (sum of the row's other
        entries), as the unbounded kernels define the model.
    """
    dense = P.toarray()
    rows = [{j: Fraction(float(v)) for j, v in enumerate(row) if v != 0} for row in dense]
    if implied_loops:
        for i, row in enumerate(rows):
            loop = 1 - sum((v for j, v in row.items() if j != i), Fraction(0))
            row.pop(i, None)
            if loop:
                row[i] = loop
    return rows


def can_reach(P: sp.csr_matrix, through: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """Seeds, or states in *through* with an edge into the set (dense fixpoint)."""
    edges = P.toarray() > 0
    reached = seeds.copy()
    for _ in range(len(seeds)):
        reached = seeds | (through & (edges.astype(int) @ reached.astype(int) > 0))
    return reached


def solve(matrix: list[list[Fraction]], rhs: list[Fraction]) -> list[Fraction]:
    """Gauss-Jordan with row pivoting over Fractions."""
    n = len(rhs)
    a = [[*row, rhs[i]] for i, row in enumerate(matrix)]
    for col in range(n):
        pivot = next(r for r in range(col, n) if a[r][col] != 0)
        a[col], a[pivot] = a[pivot], a[col]
        for r in range(n):
            if r != col and a[r][col] != 0:
                f = a[r][col] / a[col][col]
                a[r] = [x - f * y for x, y in zip(a[r], a[col], strict=True)]
    return [a[i][n] / a[i][i] for i in range(n)]


def until(P: sp.csr_matrix, remain: np.ndarray, target: np.ndarray) -> list[Fraction]:
    """Exact ``P(remain U target)`` per state."""
    rows = exact_rows(P, implied_loops=True)
    unknown = can_reach(P, remain & ~target, target) & ~target
    idx = list(np.flatnonzero(unknown))
    where = {s: i for i, s in enumerate(idx)}
    matrix = [[Fraction(int(i == j)) for j in range(len(idx))] for i in range(len(idx))]
    rhs = [Fraction(0)] * len(idx)
    for i, s in enumerate(idx):
        for t, p in rows[s].items():
            if t in where:
                matrix[i][where[t]] -= p
            elif target[t]:
                rhs[i] += p
    values = solve(matrix, rhs) if idx else []
    result = [Fraction(int(t)) for t in target]
    for s, v in zip(idx, values, strict=True):
        result[s] = v
    return result


def reach_rewards(P: sp.csr_matrix, rewards: np.ndarray, target: np.ndarray) -> list[Fraction]:
    """Exact ``R=? [F target]`` per state (None entries for infinity)."""
    everywhere = np.ones(len(target), dtype=bool)
    stuck = ~can_reach(P, everywhere, target)
    unsure = can_reach(P, ~target, stuck)
    rows = exact_rows(P, implied_loops=True)
    idx = list(np.flatnonzero(~unsure & ~target))
    where = {s: i for i, s in enumerate(idx)}
    matrix = [[Fraction(int(i == j)) for j in range(len(idx))] for i in range(len(idx))]
    rhs = [Fraction(float(rewards[s])) for s in idx]
    for i, s in enumerate(idx):
        for t, p in rows[s].items():
            if t in where:
                matrix[i][where[t]] -= p
    values = solve(matrix, rhs) if idx else []
    result: list[Fraction] = [Fraction(0)] * len(target)
    for s, v in zip(idx, values, strict=True):
        result[s] = v
    return result


def step_power(P: sp.csr_matrix, start: list[Fraction], offset: list[Fraction],
               k: int) -> list[Fraction]:
    """``k`` steps of ``x <- offset + P x`` exactly."""
    rows = exact_rows(P)
    x = start
    for _ in range(k):
        x = [offset[s] + sum((p * x[t] for t, p in rows[s].items()), Fraction(0))
             for s in range(len(x))]
    return x
