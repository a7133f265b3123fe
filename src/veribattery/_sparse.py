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


def _sharing(matrix: _Matrix, indices: npt.NDArray[np.integer],
             indptr: npt.NDArray[np.integer]) -> _Matrix:
    # (the constructor has checked them; a copy of equal dtype has equal contents)
    if matrix.indices.dtype == indices.dtype and matrix.indptr.dtype == indptr.dtype:
        matrix.indices, matrix.indptr = indices, indptr
    return matrix
