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
    least_positive,
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


@pytest.mark.parametrize("values", [
    [], [0.0, 0.0], [0.0, np.inf], [np.inf], [np.nan], [np.nan, 3.0], [-1.0, 2.0],
    [-0.0, 5e-324], [-5e-324, 0.0], [1e308, 2.2250738585072014e-308, 7.0], [2.0, 1.0, 0.5],
])
def test_least_positive_entry(values: list[float]) -> None:
    positive = [v for v in values if v > 0]
    assert least_positive(np.array(values, dtype=np.float64)) == min(positive, default=np.inf)


def test_least_positive_entry_of_random_vectors() -> None:
    rng = np.random.default_rng(3)
    for _ in range(500):
        x = rng.standard_normal(int(rng.integers(1, 40))) * 10.0 ** int(rng.integers(-320, 300))
        x[rng.random(x.size) < 0.3] = 0.0
        x[rng.random(x.size) < 0.05] = np.nan
        positive = x[x > 0]
        assert least_positive(x) == (positive.min() if positive.size else np.inf)
        assert least_positive(x[::2]) == least_positive(x[::2].copy())
