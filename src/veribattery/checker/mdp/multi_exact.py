"""An exact witness for a multi-objective achievability query on its boundary.

When the best strategy meets the bounds with no margin to spare (``R>=2.9`` where
2.9 is the optimum), floating point cannot tell "just met" from "just missed".
HiGHS returns a vertex of the programme: its nonzero variables (the *support*)
and the constraints it meets with equality determine it. Solving that square-ish
system again in rational arithmetic (gmpy2 ``mpq``; the model's probabilities,
rewards and bounds are read as the exact rationals of their doubles) and checking
every constraint exactly either proves that a strategy meets the bounds -- for
the model as built -- or proves nothing (then the answer stays undecided).
"""

from __future__ import annotations

from dataclasses import dataclass

import gmpy2
import numpy as np
import scipy.sparse as sp

from veribattery._types import FloatArray, IntArray

__all__ = ["MAX_SUPPORT", "SUPPORT_THRESHOLD", "exact_witness"]

#: Largest support solved exactly (Gaussian elimination on rationals is cubic).
MAX_SUPPORT = 2000
#: Entries of the floating-point vertex taken for zeros.
SUPPORT_THRESHOLD = 1e-9

_Row = dict[int, "gmpy2.mpq"]


@dataclass(frozen=True, slots=True)
class _System:
    """``flow x = start`` and ``rows x <= bounds`` over ``x >= 0``, in floats."""

    flow: sp.csr_matrix
    start: FloatArray
    rows: FloatArray
    bounds: FloatArray


def exact_witness(flow: sp.csr_matrix, start: FloatArray, rows: FloatArray,
                  bounds: FloatArray, point: FloatArray, tolerance: float) -> bool:
    """Whether the vertex near *point* is, in exact arithmetic, a solution of
    ``flow x = start, rows x <= bounds, x >= 0``.

    :param point: a floating-point solution (a vertex, as the simplex method gives);
        its entries above :data:`SUPPORT_THRESHOLD` are the unknowns, the others 0.
    :param tolerance: slack below which a row of *rows* counts as met with equality.
    """
    system = _System(sp.csr_matrix(flow), start, np.atleast_2d(rows), bounds)
    support = np.flatnonzero(point > SUPPORT_THRESHOLD)
    if support.size > MAX_SUPPORT:
        return False
    slack = bounds - system.rows @ point
    tight = np.flatnonzero(np.abs(slack) <= tolerance * np.maximum(1.0, np.abs(bounds)))
    found = _equations(system, support, tight)
    solution = None if found is None else _solve(*found, support.size)
    if solution is None or any(v < 0 for v in solution):
        return False
    return _meets_bounds(system, support, solution)


def _mpq(value: float) -> gmpy2.mpq:
    return gmpy2.mpq(float(value))


def _equations(system: _System, support: IntArray,
               tight: IntArray) -> tuple[list[_Row], list[gmpy2.mpq]] | None:
    """The flow rows that the support touches and the tight bound rows, over the
    support's columns; None when an untouched flow row needs a nonzero value."""
    column = {int(j): k for k, j in enumerate(support)}
    flow = system.flow[:, support].tocsr()
    touched = np.flatnonzero(np.diff(flow.indptr) > 0)
    untouched = np.ones(flow.shape[0], dtype=bool)
    untouched[touched] = False
    if np.any(system.start[untouched] != 0):
        return None
    equations, rhs = [], []
    for r in touched:  # the support's rows only (at most MAX_SUPPORT columns' worth)
        start, end = flow.indptr[r], flow.indptr[r + 1]
        equations.append({int(flow.indices[i]): _mpq(flow.data[i]) for i in range(start, end)})
        rhs.append(_mpq(system.start[r]))
    for r in tight:
        row = system.rows[r]
        equations.append({column[int(j)]: _mpq(row[j]) for j in support if row[j] != 0})
        rhs.append(_mpq(system.bounds[r]))
    return equations, rhs


def _solve(equations: list[_Row], rhs: list[gmpy2.mpq], size: int) -> list[gmpy2.mpq] | None:
    """A solution (free unknowns 0) by Gauss-Jordan elimination, None if inconsistent."""
    pivots: list[tuple[int, _Row, gmpy2.mpq]] = []
    for row, value in zip(equations, rhs, strict=True):
        row, value = dict(row), value
        for column, pivot_row, pivot_value in pivots:
            factor = row.get(column)
            if factor:
                value -= factor * pivot_value
                for j, a in pivot_row.items():
                    row[j] = row.get(j, 0) - factor * a
                row = {j: a for j, a in row.items() if a != 0}
        if not row:
            if value != 0:
                return None
            continue
        column = min(row)
        scale = row[column]
        pivots.append((column, {j: a / scale for j, a in row.items()}, value / scale))
    return _back_substituted(pivots, size)


def _back_substituted(pivots: list[tuple[int, _Row, gmpy2.mpq]],
                      size: int) -> list[gmpy2.mpq]:
    """Unknowns from the echelon rows, last pivot first."""
    solution = [gmpy2.mpq(0)] * size
    for column, row, value in reversed(pivots):
        solution[column] = value - sum((a * solution[j] for j, a in row.items() if j != column),
                                       gmpy2.mpq(0))
    return solution


def _meets_bounds(system: _System, support: IntArray, solution: list[gmpy2.mpq]) -> bool:
    """Every bound row, exactly (the flow rows hold by construction: the solution
    solves them in exact arithmetic, and the rows outside the support are 0 = 0)."""
    for row, bound in zip(system.rows, system.bounds, strict=True):
        total = sum((_mpq(row[j]) * v for j, v in zip(support, solution, strict=True)
                     if row[j] != 0), gmpy2.mpq(0))
        if total > _mpq(bound):
            return False
    return True
