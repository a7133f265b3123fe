"""AffineMap.images: the in-place evaluation (and the shared numerator when both sides
are taken at one vector) is bit for bit the documented formula
``step_up(step_up(num + err) / leave_lower)`` / ``step_down(step_down(num - err) /
leave_upper)`` with ``err = step_up(coefficient * num + underflow)``."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from veribattery.checker import certify
from veribattery.checker.certify.rounding import step_down, step_up


def _reference(F: certify.AffineMap, x: np.ndarray, *, up: bool) -> np.ndarray:
    full = (F.known_upper if up else F.known_lower).copy()
    full[F.states] = x
    numerator = np.asarray(F.rows @ full, dtype=np.float64)
    if F.offset is not None:
        numerator = numerator + F.offset
    error = step_up(F.coefficient * numerator + F.underflow)
    with np.errstate(divide="ignore", invalid="ignore"):
        if up:
            above = step_up(step_up(numerator + error) / F.leave_lower)
            return np.where(np.isnan(above), np.inf, above)
        below = step_down(step_down(numerator - error) / F.leave_upper)
    return np.where(np.isnan(below), -np.inf, np.maximum(below, 0.0))


def _map(seed: int, same_known: bool) -> certify.AffineMap:
    rng = np.random.default_rng(seed)
    n = 600
    P = sp.random(n, n, density=0.01, random_state=seed, format="csr")
    P.data = rng.random(P.nnz)
    sums = np.maximum(np.asarray(P.sum(axis=1)).ravel(), 1e-300)
    P = sp.csr_matrix(P.multiply(1 / sums[:, None]))
    states = np.arange(0, n, 2)
    known = np.where(np.arange(n) % 2 == 1, rng.random(n), 0.0)
    upper = known if same_known else known * 1.25
    offset = None if same_known else rng.random(states.size) * (rng.random(states.size) < 0.5)
    return certify.AffineMap.of(sp.csr_matrix(P[states]), states, known, upper, offset)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("same_known", [True, False])
def test_images_equal_the_formula_bit_for_bit(seed: int, same_known: bool) -> None:
    F = _map(seed, same_known)
    rng = np.random.default_rng(100 + seed)
    for scale in (1e-310, 1e-200, 1e-20, 1.0, 1e6):
        x = rng.random(F.states.size) * scale
        x[rng.random(x.size) < 0.1] = 0.0
        for low, high in ((x, x), (x, x * 2)):
            below, above = F.images(low, high)
            assert np.array_equal(below, _reference(F, low, up=False))
            assert np.array_equal(above, _reference(F, high, up=True))
