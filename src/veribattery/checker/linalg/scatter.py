"""``M^T x`` at the cost of *x*'s nonzeros, with the sums of ``(M^T) @ x``.

A forward pass over reward levels (``reward_bounded.absorption_by_level``) moves, at
each level, the mass that leaves a few states: on the mission's Case 1 at most
about 1,200 of 162,270 sources carry mass at a level, yet a sparse product visits every
stored entry. :class:`TransposedProduct` visits only the rows of *M* whose entry of *x*
is nonzero when they are few.

Every target's terms are added in the order of their source (ascending), starting from
zero, each product rounded once -- exactly what ``csr_matvec`` does with the transposed
matrix's sorted rows -- and a term skipped has the value ``+0.0`` (sources with ``x_j =
0``), which leaves every sum as it is. So both paths give the same floats.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from veribattery._types import CsrMatrix, FloatArray

__all__ = ["SPARSE_SHARE", "TransposedProduct"]

#: Above this share of nonzero entries in *x* the whole transposed matrix is used.
SPARSE_SHARE = 0.02


class TransposedProduct:
    """``x -> M^T x`` for a CSR matrix *M*."""

    __slots__ = ("_rows", "_transposed")

    def __init__(self, rows: CsrMatrix) -> None:
        self._rows = sp.csr_matrix(rows)
        self._rows.sort_indices()
        self._transposed = sp.csr_matrix(self._rows.T)
        self._transposed.sort_indices()

    def __call__(self, x: FloatArray) -> FloatArray:
        """``M^T x`` (a new array) for a finite *x*."""
        sources = np.nonzero(x != 0)[0]  # (a boolean mask first: 7x faster than flatnonzero)
        if sources.size > SPARSE_SHARE * x.size:
            return np.asarray(self._transposed @ x, dtype=np.float64)
        indptr = self._rows.indptr
        starts, sizes = indptr[sources], indptr[sources + 1] - indptr[sources]
        # entry t of source i is starts[i] + (t - first t of i)
        entries = np.repeat(starts - (np.cumsum(sizes) - sizes), sizes) + np.arange(
            int(sizes.sum()))
        terms = self._rows.data[entries] * np.repeat(x[sources], sizes)
        return np.bincount(self._rows.indices[entries], weights=terms,
                           minlength=self._rows.shape[1]).astype(np.float64, copy=False)
