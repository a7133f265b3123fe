"""product_error skips making the subnormal underflow term where it cannot count: the
same floats as the formula written out, on magnitudes across the whole range; and
zero_terms_only tells a row whose every term reads a 0 from one that underflowed."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from veribattery.checker.certify import (
    ETA,
    UNIT_ROUNDOFF,
    enclose_product,
    product_error,
    step_up,
)
from veribattery.checker.certify.apriori import zero_terms_only

_SAFETY = 1.0 + 2.0**-30  # (the factor the module documents)


def _written_out(magnitude: np.ndarray, roundings: np.ndarray,
                 underflows: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore", invalid="ignore"):
        bound = (4.0 * UNIT_ROUNDOFF) * roundings * magnitude * _SAFETY + underflows * (2 * ETA)
        bound = np.where(np.isnan(bound), np.inf, bound)
        return np.where(bound > 0, step_up(bound), 0.0)


@pytest.mark.parametrize("seed", range(4))
def test_the_same_floats_as_the_formula(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 20_000
    # magnitudes from subnormal to huge, with zeros, infinities and NaN, and some right
    # at the threshold where the underflow term stops counting
    magnitude = rng.random(n) * 2.0 ** rng.integers(-1074, 1000, n).astype(float)
    magnitude[:50] = 0.0
    magnitude[50:60] = np.inf
    magnitude[60:70] = np.nan
    magnitude[70:400] = 2.0**-900 * (1 + rng.integers(-3, 4, 330) * 2.0**-52) * 2.0**51
    roundings = rng.integers(0, 50, n).astype(float)
    roundings[rng.random(n) < 0.1] = 0.0  # no rounding, yet products that underflow
    for underflows in (roundings, np.zeros(n), rng.integers(0, 2**40, n).astype(float),
                       np.full(n, 2.0**120)):
        got = product_error(magnitude, roundings, underflows)
        expected = _written_out(magnitude, roundings, underflows)
        assert got.view(np.int64).tolist() == expected.view(np.int64).tolist()


def test_the_rows_whose_terms_all_read_zeros() -> None:
    # Rows 0 and 2 read only x_j = 0: exactly 0. Row 1's product underflows to 0
    # (0.25 * 2**-1074): its exact value is positive.
    M = sp.csr_matrix(np.array([[0.5, 0.5, 0.0], [0.0, 0.0, 0.25], [0.3, 0.0, 0.0]]))
    x = np.array([0.0, 0.0, ETA])
    product, lower, upper = enclose_product(M, x)
    silent = product == 0
    assert silent.tolist() == [True, True, True]
    assert zero_terms_only(M, x, silent).tolist() == [True, False, True]
    assert lower[1] <= 0.0 < Fraction(ETA) / 4 <= Fraction(upper[1])
    # No product can underflow: every silent row reads only zeros.
    y = np.array([0.0, 0.0, 0.5])
    assert zero_terms_only(M, y, M @ y == 0).tolist() == [True, False, True]
    assert (M @ y).tolist() == [0.0, 0.125, 0.0]
