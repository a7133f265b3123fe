"""A priori bounds of nonnegative products (certify.apriori) against exact rational
products: enclosed, exact 0s kept, and refused where a product may underflow."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from veribattery.checker.certify.apriori import (
    NO_UNDERFLOW,
    NonnegativeProducts,
    float_above,
    float_below,
    gamma,
)


def _exact(matrix: sp.csr_matrix, x: np.ndarray) -> list[Fraction]:
    return [sum((Fraction(float(p)) * Fraction(float(x[j]))
                 for p, j in zip(matrix.data[a:b], matrix.indices[a:b], strict=True)),
                Fraction(0))
            for a, b in zip(matrix.indptr[:-1], matrix.indptr[1:], strict=True)]


def test_floats_either_side_of_a_rational() -> None:
    third = Fraction(1, 3)
    assert Fraction(float_below(third)) < third < Fraction(float_above(third))
    assert float_above(third) == np.nextafter(float_below(third), 1.0)
    assert float_below(Fraction(1, 4)) == float_above(Fraction(1, 4)) == 0.25
    assert gamma(0) == 0 and gamma(2) == Fraction(2, 2**53 - 2)


@pytest.mark.parametrize("seed", range(6))
def test_bounds_enclose_the_exact_products(seed: int) -> None:
    rng = np.random.default_rng(seed)
    dense = rng.random((40, 30)) * (rng.random((40, 30)) < 0.3)
    dense[:, 0] += 0.01  # (every row an entry)
    dense /= dense.sum(axis=1, keepdims=True)
    matrix = sp.csr_matrix(dense)
    x = rng.random(30) * (rng.random(30) < 0.7) * 10.0 ** rng.integers(-200, 1, 30)
    x[0] = 0.0
    products = NonnegativeProducts.of(matrix)
    lower, upper = products.bound(x, up=False), products.bound(x, up=True)
    assert lower is not None and upper is not None
    for low, high, exact in zip(lower, upper, _exact(matrix, x), strict=True):
        assert Fraction(float(low)) <= exact <= Fraction(float(high))
        if exact == 0:
            assert low == high == 0.0  # (a row that reads only 0s)
        else:
            assert float(high - low) <= 1e-14 * float(exact)


def test_a_product_that_may_underflow_is_refused() -> None:
    matrix = sp.csr_matrix(np.array([[0.5, 0.5], [1e-10, 1.0 - 1e-10]]))
    products = NonnegativeProducts.of(matrix)
    tiny = NO_UNDERFLOW / 1e-10 / 2  # (times the smallest entry: below the threshold)
    assert products.bound(np.array([tiny, 0.0]), up=True) is None
    assert products.bound(np.array([tiny * 4, 0.0]), up=True) is not None
    assert products.bound(np.zeros(2), up=True).tolist() == [0.0, 0.0]  # type: ignore[union-attr]
