"""A sparse LU kept as its two triangular factors, without SuperLU's working memory.

A ``SuperLU`` object keeps the arrays its factorisation grew in, sized for the fill
SuperLU expected, not the fill it found: a strategy's system on zeroconf (K=4,
213,268 states, 471,811 entries) holds 41 MB where its factors have 1,036,497
entries (12 MB); resource-gathering's strategy, solved as 199 runs of small
components, held 87 MB for factors of 2 MB. A solver that lives on (a component of
:class:`~veribattery.checker.linalg.topological.TopologicalSolver`, kept with a
strategy's evaluation through the certificate) keeps the factors alone.

The solve is SuperLU's triangular solve on the factors, the one ``spsolve_triangular``
calls; it sums in another order than the ``SuperLU`` object's own (by columns, not
supernodes), so its results agree to rounding, not bit for bit. Whether that private
entry point behaves as expected is probed once per process; otherwise the ``SuperLU``
object is kept.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import SuperLU, splu, spsolve_triangular

from veribattery._types import FloatArray

try:  # SuperLU's triangular solve, on the factors as arrays
    from scipy.sparse.linalg._dsolve import _superlu
except ImportError:  # pragma: no cover -- scipy moved it: the SuperLU object is kept
    _superlu = None

__all__ = ["compact_solve", "unit_lower_solve"]

#: A CSC matrix as SuperLU's triangular solve reads it: entries, data, row indices,
#: pointers.
_Arrays = tuple[int, FloatArray, np.ndarray, np.ndarray]

#: Whether the private triangular solve agreed with ``SuperLU.solve`` (None: not probed).
_agrees: bool | None = None
#: ... and with ``spsolve_triangular`` on a unit lower triangular matrix.
_triangular_agrees: bool | None = None


def compact_solve(lu: SuperLU) -> Callable[[FloatArray], FloatArray]:
    """``A^-1 b`` from the factors of *lu* (``Pr A Pc = L U``), without *lu* itself
    where the triangular solve behaves as expected, else *lu*'s own solve."""
    global _agrees
    if _superlu is not None and _agrees is None:
        _agrees = _factors_probe()
    if _superlu is None or not _agrees:
        return lu.solve  # type: ignore[no-any-return]
    return _factors_solve(lu)


def _factors_probe() -> bool:
    """Whether the solve on the factors gives the SuperLU object's, on a small system
    with row and column exchanges. (Once probed on the first system a process met, an
    ill-conditioned one -- two summation orders 1e-9 apart -- turned the compact solve
    off for the whole process.)"""
    A = sp.csc_matrix(np.array([[0.1, 2.0, 0.0, 1.0], [3.0, 0.2, 1.0, 0.0],
                                [0.0, 1.0, 0.3, 4.0], [1.0, 0.0, 5.0, 0.4]]))
    probe = np.linspace(1.0, 2.0, 4)
    try:
        lu = splu(A)
        return bool(np.allclose(_factors_solve(lu)(probe.copy()), lu.solve(probe),
                                rtol=1e-12, atol=0.0))
    except Exception:  # (any failure of the private path: the SuperLU object is kept)
        return False


def unit_lower_solve(lower: sp.csc_matrix) -> Callable[[FloatArray], FloatArray] | None:
    """``b -> lower^-1 b`` (*b* overwritten) for a lower triangular CSC with its unit
    diagonal stored and sorted rows, or None where SuperLU's triangular solve is not
    there or not as expected (then ``spsolve_triangular``).

    The routine ``spsolve_triangular(lower, b, lower=True, unit_diagonal=True,
    overwrite_A=True, overwrite_b=True)`` calls (scipy >= 1.14), on the same arrays,
    made once: that function checks, sets the diagonal and casts the index arrays at
    every call, 0.2 ms each, and a strategy's system on consensus is solved through
    some forty runs of single-state components, several times per evaluation.
    """
    global _triangular_agrees
    if _superlu is not None and _triangular_agrees is None:
        _triangular_agrees = _triangular_probe()
    if _superlu is None or not _triangular_agrees:
        return None
    return _lower_solve(lower)


def _lower_solve(lower: sp.csc_matrix) -> Callable[[FloatArray], FloatArray]:
    n = int(lower.shape[0])
    arrays = _arrays(lower)
    empty = (0, np.zeros(0, dtype=np.float64), np.zeros(0, dtype=np.intc),
             np.zeros(n + 1, dtype=np.intc))

    def solve(b: FloatArray) -> FloatArray:
        return _gstrs(n, arrays, empty, np.ascontiguousarray(b, dtype=np.float64))

    return solve


def _triangular_probe() -> bool:
    """Whether the private path gives ``spsolve_triangular``'s result, bit for bit, on
    a small system (whose rounding makes the order of the sums show)."""
    lower = sp.csc_matrix(np.array([[1.0, 0.0, 0.0, 0.0], [-0.1, 1.0, 0.0, 0.0],
                                    [-0.7, -0.3, 1.0, 0.0], [-0.2, -0.6, -0.9, 1.0]]))
    b = np.array([0.3, 0.7, 0.1, 0.9])
    try:
        expected = spsolve_triangular(lower.copy(), b.copy(), lower=True, unit_diagonal=True)
        return bool(np.array_equal(_lower_solve(lower)(b.copy()), expected))
    except Exception:  # (any failure of the private path: scipy's own function is used)
        return False


def _factors_solve(lu: SuperLU) -> Callable[[FloatArray], FloatArray]:
    """The solve on *lu*'s factors as the triangular solve takes them: the unit lower
    factor's strict part with the upper factor's diagonal, and the strict upper part."""
    n = int(lu.shape[0])
    lower, upper = _triangles(lu)
    lower_arrays = _arrays(lower)
    upper_arrays = _arrays(upper)
    rows, columns = np.asarray(lu.perm_r), np.asarray(lu.perm_c)
    rows_kept = None if np.array_equal(rows, np.arange(n)) else rows
    columns_kept = None if np.array_equal(columns, np.arange(n)) else columns
    del lower, upper, rows, columns

    def solve(b: FloatArray) -> FloatArray:
        permuted = np.empty(n, dtype=np.float64)
        if rows_kept is None:
            permuted[:] = b
        else:
            permuted[rows_kept] = b
        x = _gstrs(n, lower_arrays, upper_arrays, permuted)
        return x if columns_kept is None else x[columns_kept]

    return solve


def _gstrs(n: int, lower: _Arrays, upper: _Arrays, b: FloatArray) -> FloatArray:
    """SuperLU's triangular solve of ``L U x = b`` on the arrays of *lower* (its
    diagonal is ``U``'s) and *upper* (strict), *b* overwritten."""
    x, info = _superlu.gstrs("N", n, *lower, n, *upper, b)
    if info:
        raise RuntimeError("triangular solve failed")
    return np.asarray(x, dtype=np.float64)


def _triangles(lu: SuperLU) -> tuple[sp.csc_matrix, sp.csc_matrix]:
    """The lower factor's strict part with the upper factor's diagonal (explicit zeros
    dropped), and the upper factor's strict part (explicit zeros kept).

    Read off the factors' arrays where every column of ``L`` starts with its diagonal
    and every column of ``U`` ends with it (sorted rows, as SuperLU gives them): ~0.1 ms
    for a component of a few hundred states, where ``tril``, ``diags``, their sum and
    ``triu`` took 0.4-0.7 ms -- most of making the solver of a small component, and a
    strategy's system on consensus has some forty such. Otherwise by those operations,
    which give the same arrays.
    """
    lower, upper = sp.csc_matrix(lu.L), sp.csc_matrix(lu.U)
    lower.sort_indices()
    upper.sort_indices()
    n = int(lu.shape[0])
    diagonal_first, diagonal_last = lower.indptr[:-1], upper.indptr[1:] - 1
    columns = np.arange(n)
    if (n and np.all(np.diff(lower.indptr) > 0) and np.all(np.diff(upper.indptr) > 0)
            and np.array_equal(lower.indices[diagonal_first], columns)
            and np.array_equal(upper.indices[diagonal_last], columns)):
        data = lower.data.copy()
        data[diagonal_first] = upper.data[diagonal_last]
        strict_lower = sp.csc_matrix((data, lower.indices, lower.indptr), shape=lower.shape)
        # (the sum below drops the zeros it makes or is given; triu keeps stored ones)
        strict_lower.eliminate_zeros()
        off_diagonal = np.ones(upper.nnz, dtype=bool)
        off_diagonal[diagonal_last] = False
        indptr = upper.indptr - np.arange(n + 1, dtype=upper.indptr.dtype)
        return strict_lower, sp.csc_matrix((upper.data[off_diagonal],
                                            upper.indices[off_diagonal], indptr),
                                           shape=upper.shape)
    return (sp.csc_matrix(sp.tril(lower, -1, format="csc") + sp.diags(upper.diagonal())),
            sp.csc_matrix(sp.triu(upper, 1, format="csc")))


def _arrays(matrix: sp.csc_matrix) -> _Arrays:
    """*matrix* as the triangular solve reads it: entries, data, row indices, pointers."""
    matrix.sort_indices()
    return (int(matrix.nnz), np.ascontiguousarray(matrix.data, dtype=np.float64),
            np.ascontiguousarray(matrix.indices, dtype=np.intc),
            np.ascontiguousarray(matrix.indptr, dtype=np.intc))
