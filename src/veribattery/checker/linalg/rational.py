"""Exact rational solution of small fixed-point systems: the last resort of the unbounded kernels.

Badly conditioned systems (Haddad and Monmege's chain has condition number
~2^N) defeat every floating-point method, but when they are small they can be
solved exactly: each float64 entry is a dyadic rational, so
``(I - P_mm) x = c`` has an exact rational solution, found here by sparse
Gaussian elimination over :class:`fractions.Fraction` in a fill-reducing order
(SuperLU's minimum-degree ordering of the same pattern). ``I - P_mm`` is a
nonsingular M-matrix after the 0/1 pre-pass, so every pivot in any symmetric
order is positive and no pivoting is needed.

This is the one place in the checker that loops over states in Python; it only
runs on systems below :data:`EXACT_LIMIT` unknowns whose float certificate failed.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import scipy.sparse as sp
from scipy.sparse import linalg as spla

from veribattery._types import FloatArray, IntArray
from veribattery.checker.certify.affine import AffineMap
from veribattery.checker.certify.bounds import rational_bounds

#: Largest number of unknowns solved exactly.
EXACT_LIMIT = 5_000
#: Give up when elimination has created this many entries (fill-in).
FILL_LIMIT = 2_000_000

_Row = dict[int, Fraction]


def solve_exact(F: AffineMap) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """The fixed point of *F* in exact arithmetic, rounded to ``(value, lower, upper)``.

    :return: nearest floats and outward-rounded bounds (``lower <= x* <= upper``),
        or None when the system is too large, fills in too much, or its known
        values are not exact.
    """
    n = F.states.size
    if n > EXACT_LIMIT or not np.array_equal(F.known_lower, F.known_upper):
        return None
    rows, rhs = _equations(F)
    solution = _eliminate(rows, rhs, _order(F))
    return None if solution is None else _rounded(solution)


def _equations(F: AffineMap) -> tuple[list[_Row], list[Fraction]]:
    """``(I - P_mm)`` as exact sparse rows and ``c = offset + P_mk known`` exactly."""
    local = np.full(F.rows.shape[1], -1, dtype=np.int64)
    local[F.states] = np.arange(F.states.size)
    rows: list[_Row] = []
    rhs: list[Fraction] = []
    indptr, indices, data = F.rows.indptr, F.rows.indices, F.rows.data
    for a in range(F.states.size):
        # F.rows has no diagonal: the self-loop is 1 - (leaving probability), so
        # the diagonal of I - P is the leaving probability itself.
        row: _Row = {a: Fraction(0)}
        c = Fraction(float(F.offset[a])) if F.offset is not None else Fraction(0)
        for j, p in zip(indices[indptr[a]:indptr[a + 1]].tolist(),
                        data[indptr[a]:indptr[a + 1]].tolist(), strict=True):
            b = int(local[j])
            row[a] += Fraction(p)
            if b < 0:
                c += Fraction(p) * Fraction(float(F.known_lower[j]))
            else:
                row[b] = row.get(b, Fraction(0)) - Fraction(p)
        rows.append({k: v for k, v in row.items() if v != 0})
        rhs.append(c)
    return rows, rhs


def _order(F: AffineMap) -> IntArray:
    """A fill-reducing elimination order: SuperLU's minimum degree on ``A^T + A``."""
    inner = sp.csc_matrix(F.rows[:, F.states])
    A = sp.csc_matrix(sp.eye(F.states.size) - inner + sp.eye(F.states.size) * 1e-3)
    try:
        lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
        return np.asarray(np.argsort(lu.perm_c), dtype=np.int64)
    except RuntimeError:
        return np.arange(F.states.size, dtype=np.int64)


def _eliminate(rows: list[_Row], rhs: list[Fraction], order: IntArray) -> list[Fraction] | None:
    """Gaussian elimination in *order*, then back substitution (None past the fill limit)."""
    columns: list[set[int]] = [set() for _ in rows]
    for r, row in enumerate(rows):
        for c in row:
            columns[c].add(r)
    done: set[int] = set()
    fill = 0
    for k in order.tolist():
        pivot = rows[k].get(k)
        if not pivot:
            return None
        for r in columns[k] - done - {k}:
            fill += _subtract(rows, columns, r, k, rhs)
        done.add(k)
        if fill > FILL_LIMIT:
            return None
    return _back_substitute(rows, rhs, order)


def _subtract(rows: list[_Row], columns: list[set[int]], r: int, k: int,
              rhs: list[Fraction]) -> int:
    """Row r -= (a_rk / a_kk) row k; returns the number of entries touched."""
    factor = rows[r].pop(k) / rows[k][k]
    columns[k].discard(r)
    for c, v in rows[k].items():
        if c == k:
            continue
        new = rows[r].get(c, Fraction(0)) - factor * v
        if new:
            rows[r][c] = new
            columns[c].add(r)
        else:
            rows[r].pop(c, None)
            columns[c].discard(r)
    rhs[r] -= factor * rhs[k]
    return len(rows[k])


def _back_substitute(rows: list[_Row], rhs: list[Fraction], order: IntArray) -> list[Fraction]:
    x: list[Fraction] = [Fraction(0)] * len(rows)
    for k in reversed(order.tolist()):
        row = rows[k]
        total = rhs[k] - sum((v * x[c] for c, v in row.items() if c != k), Fraction(0))
        x[k] = total / row[k]
    return x


def _rounded(solution: list[Fraction]) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Nearest floats and directed neighbours (``inf`` above the largest double)."""
    found = rational_bounds(solution)
    return found.value, found.lower, found.upper


#: Largest ``steps * stored entries`` of a step-bounded iteration done exactly.
POWER_LIMIT = 1_000_000


def power_exact(M: sp.csr_matrix, start: FloatArray, offset: FloatArray,
                k: int) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """``k`` steps of ``x <- offset + M x`` from *start* in exact arithmetic, rounded
    to ``(value, lower, upper)``; None when ``k * nnz`` exceeds :data:`POWER_LIMIT`.

    The step-bounded kernels' last resort when a bound must be decided at a value
    the float iteration's error bar straddles (``P>0.98`` where it is exactly 0.98).
    Entries are dyadic rationals (:class:`gmpy2.mpq`); the products are vectorised
    over object arrays, and the iteration stops at an exact fixpoint.
    """
    from gmpy2 import mpq

    if k * max(M.nnz, 1) > POWER_LIMIT or M.shape[0] > EXACT_LIMIT:
        return None
    exact = np.frompyfunc(mpq, 1, 1)
    data, x, base = exact(M.data), exact(start), exact(offset)
    rows = np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))
    for _ in range(k):
        following = base.copy()
        np.add.at(following, rows, data * x[M.indices])
        if np.array_equal(following, x):
            break
        x = following
    return _rounded([Fraction(int(v.numerator), int(v.denominator)) for v in x])
