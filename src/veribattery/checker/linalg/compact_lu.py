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
from scipy.sparse.linalg import SuperLU

from veribattery._types import FloatArray

try:  # SuperLU's triangular solve, on the factors as arrays
    from scipy.sparse.linalg._dsolve import _superlu
except ImportError:  # pragma: no cover -- scipy moved it: the SuperLU object is kept
    _superlu = None

__all__ = ["compact_solve"]

#: Whether the private triangular solve agreed with ``SuperLU.solve`` (None: not probed).
_agrees: bool | None = None


def compact_solve(lu: SuperLU) -> Callable[[FloatArray], FloatArray]:
    """``A^-1 b`` from the factors of *lu* (``Pr A Pc = L U``), without *lu* itself
    where the triangular solve behaves as expected, else *lu*'s own solve."""
    global _agrees
    if _superlu is None or _agrees is False:
        return lu.solve  # type: ignore[no-any-return]
    solve = _factors_solve(lu)
    if _agrees is None:
        probe = np.linspace(1.0, 2.0, lu.shape[0])
        try:
            _agrees = bool(np.allclose(solve(probe.copy()), lu.solve(probe), rtol=1e-9,
                                       atol=0.0))
        except Exception:  # (any failure of the private path: the SuperLU object is kept)
            _agrees = False
        if not _agrees:
            return lu.solve  # type: ignore[no-any-return]
    return solve


def _factors_solve(lu: SuperLU) -> Callable[[FloatArray], FloatArray]:
    """The solve on *lu*'s factors as the triangular solve takes them: the unit lower
    factor's strict part with the upper factor's diagonal, and the strict upper part."""
    n = int(lu.shape[0])
    upper = sp.csc_matrix(lu.U)
    lower = sp.csc_matrix(sp.tril(lu.L, -1, format="csc") + sp.diags(upper.diagonal()))
    upper = sp.csc_matrix(sp.triu(upper, 1, format="csc"))
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
        x, info = _superlu.gstrs("N", n, *lower_arrays, n, *upper_arrays, permuted)
        if info:
            raise RuntimeError("triangular solve failed")
        x = np.asarray(x, dtype=np.float64)
        return x if columns_kept is None else x[columns_kept]

    return solve


def _arrays(matrix: sp.csc_matrix) -> tuple[int, FloatArray, np.ndarray, np.ndarray]:
    """*matrix* as the triangular solve reads it: entries, data, row indices, pointers."""
    matrix.sort_indices()
    return (int(matrix.nnz), np.ascontiguousarray(matrix.data, dtype=np.float64),
            np.ascontiguousarray(matrix.indices, dtype=np.intc),
            np.ascontiguousarray(matrix.indptr, dtype=np.intc))
