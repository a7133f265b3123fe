"""The distinct values of an integer array, by sorting.

numpy 2.3 and later find distinct values by hashing in ``np.unique`` (alone, or with
``return_index`` or ``return_inverse``): on 2 million integers that takes 0.2-1.1 s
where a sort takes 0.05 s (numpy 2.4). These functions give ``np.unique``'s results,
the same arrays, by one sort; the engine calls them on arrays the size of a model.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
import numpy.typing as npt

__all__ = ["distinct", "distinct_first", "distinct_inverse"]

_Int = TypeVar("_Int", bound=np.integer)


def distinct(values: npt.NDArray[_Int]) -> npt.NDArray[_Int]:
    """``np.unique(values)``: the distinct values, ascending."""
    ordered = np.sort(values, axis=None)
    return ordered[_starts(ordered)]


def distinct_first(values: npt.NDArray[_Int]) -> tuple[npt.NDArray[_Int], npt.NDArray[np.intp]]:
    """``np.unique(values, return_index=True)``: the distinct values, ascending, and
    where each first occurs (a stable sort keeps equal values in their order)."""
    order = np.argsort(values, axis=None, kind="stable")
    ordered = values.ravel()[order]
    starts = _starts(ordered)
    return ordered[starts], order[starts]


def distinct_inverse(values: npt.NDArray[_Int]) -> tuple[npt.NDArray[_Int], npt.NDArray[np.intp]]:
    """``np.unique(values, return_inverse=True)`` (of a 1-d array): the distinct values,
    ascending, and each value's position among them."""
    order = np.argsort(values, axis=None, kind="stable")
    ordered = values.ravel()[order]
    starts = _starts(ordered)
    inverse = np.empty(ordered.size, dtype=np.intp)
    inverse[order] = np.cumsum(starts) - 1
    return ordered[starts], inverse.reshape(values.shape)


def _starts(ordered: npt.NDArray[np.integer]) -> npt.NDArray[np.bool_]:
    """Where a run of equal values begins in the sorted *ordered*."""
    starts = np.ones(ordered.size, dtype=bool)
    np.not_equal(ordered[1:], ordered[:-1], out=starts[1:])
    return starts
