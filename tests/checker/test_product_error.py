"""product_error skips making the subnormal underflow term where it cannot count: the
same floats as the formula written out, on magnitudes across the whole range."""

from __future__ import annotations

import numpy as np
import pytest

from veribattery.checker.certify import ETA, UNIT_ROUNDOFF, product_error, step_up

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
