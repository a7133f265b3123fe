"""The sort-based distinct values equal ``np.unique``'s, array for array."""

from __future__ import annotations

import numpy as np
import pytest

from veribattery._unique import distinct, distinct_first, distinct_inverse


def _cases() -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    return [np.array([], dtype=np.int64), np.array([5], dtype=np.int32),
            np.array([3, 3, 3], dtype=np.int64), np.array([2, -1, 2, 0, -1], dtype=np.int64),
            *(rng.integers(0, high, size, dtype=dtype)
              for high, size, dtype in ((4, 50, np.int64), (1000, 5000, np.int32),
                                        (2**40, 3000, np.int64), (50, 20000, np.intp)))]


@pytest.mark.parametrize("values", _cases())
def test_equal_to_numpy_unique(values: np.ndarray) -> None:
    found = distinct(values)
    assert found.dtype == values.dtype
    np.testing.assert_array_equal(found, np.unique(values))
    unique, first = distinct_first(values)
    expected, expected_first = np.unique(values, return_index=True)
    np.testing.assert_array_equal(unique, expected)
    np.testing.assert_array_equal(first, expected_first)  # the first occurrence of each
    unique, inverse = distinct_inverse(values)
    expected, expected_inverse = np.unique(values, return_inverse=True)
    np.testing.assert_array_equal(unique, expected)
    np.testing.assert_array_equal(inverse, expected_inverse)
    np.testing.assert_array_equal(unique[inverse], values)
