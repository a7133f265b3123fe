"""Sparse matrices that keep the index arrays they are given.

scipy's CSR/CSC constructors copy ``indices`` even when its dtype already fits. A
structure-reusing sweep builds its matrices of each point from index arrays kept
with a plan; sharing them saves the copy and lets the pattern memos, keyed by the
arrays' identity (``linalg.index_digest``), recognise the pattern without hashing
it again.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from veribattery._types import FloatArray

_Matrix = TypeVar("_Matrix", sp.csr_matrix, sp.csc_matrix)


def csr_sharing(data: FloatArray, indices: npt.NDArray[np.integer],
                indptr: npt.NDArray[np.integer], shape: tuple[int, int]) -> sp.csr_matrix:
    """``csr_matrix((data, indices, indptr), shape)`` holding *indices* and *indptr*
    themselves where scipy keeps their dtype (they must not be modified afterwards)."""
    return _sharing(sp.csr_matrix((data, indices, indptr), shape=shape), indices, indptr)


def csc_sharing(data: FloatArray, indices: npt.NDArray[np.integer],
                indptr: npt.NDArray[np.integer], shape: tuple[int, int]) -> sp.csc_matrix:
    """:func:`csr_sharing` for a CSC matrix."""
    return _sharing(sp.csc_matrix((data, indices, indptr), shape=shape), indices, indptr)


def csr_rows(matrix: sp.csr_matrix, first: int, last: int,
             dtype: npt.DTypeLike | None = None) -> sp.csr_matrix:
    """Rows ``first..last-1`` of *matrix* holding views of its entries (row slicing
    copies them); with *dtype*, those rows' values converted to it."""
    start, stop = int(matrix.indptr[first]), int(matrix.indptr[last])
    data = matrix.data[start:stop]
    return sp.csr_matrix((data if dtype is None else data.astype(dtype),
                          matrix.indices[start:stop], matrix.indptr[first:last + 1] - start),
                         shape=(last - first, matrix.shape[1]))


def _sharing(matrix: _Matrix, indices: npt.NDArray[np.integer],
             indptr: npt.NDArray[np.integer]) -> _Matrix:
    # (the constructor has checked them; a copy of equal dtype has equal contents)
    if matrix.indices.dtype == indices.dtype and matrix.indptr.dtype == indptr.dtype:
        matrix.indices, matrix.indptr = indices, indptr
    return matrix
