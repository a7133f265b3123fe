"""Step-bounded iteration with one radius for all states (one product per step).

The normwise radius is taken when it meets the absolute precision everywhere;
otherwise the componentwise radius runs. Both intervals must contain the exact
values (dense Fraction iteration on the float64 entries taken as exact).
"""

from __future__ import annotations

from collections.abc import Iterator
from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker import exact_reference as ref
from veribattery.checker import kernels
from veribattery.checker.certify.bounds import Bounds, required_precision
from veribattery.checker.kernels import steps


def _random_chain(seed: int, n: int = 12) -> tuple[sp.csr_matrix, np.ndarray]:
    rng = np.random.default_rng(seed)
    dense = (rng.random((n, n)) < 0.35) * rng.random((n, n))
    dense[np.arange(n), rng.integers(0, n, n)] += 0.1  # no empty row
    dense /= dense.sum(axis=1, keepdims=True)
    target = np.zeros(n, dtype=bool)
    target[rng.choice(n, 2, replace=False)] = True
    return sp.csr_matrix(dense), target


def _exact(P: sp.csr_matrix, target: np.ndarray, k: int) -> list[Fraction]:
    moving = sp.diags((~target).astype(float)) @ P  # target rows stop moving
    hit = [Fraction(int(t)) for t in target]
    return ref.step_power(sp.csr_matrix(moving), hit, hit, k)


def _contains(found: Bounds, exact: list[Fraction]) -> bool:
    return all(Fraction(float(lo)) <= e <= Fraction(float(hi))
               for lo, e, hi in zip(found.lower, exact, found.upper, strict=True))


@pytest.fixture
def paths(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[str]]:
    """Which radius each step-bounded iteration used."""
    taken: list[str] = []
    normwise = steps._step_power_normwise

    def spy(*args: object) -> Bounds | None:
        found = normwise(*args)  # type: ignore[arg-type]
        taken.append("componentwise" if found is None else "normwise")
        return found

    monkeypatch.setattr(steps, "_step_power_normwise", spy)
    yield taken


@pytest.mark.parametrize("seed", range(8))
def test_normwise_radius_contains_the_exact_values(seed: int, paths: list[str]) -> None:
    P, target = _random_chain(seed)
    k = 25
    found = kernels.bounded_until_probs(P, np.ones(len(target), dtype=bool), target, k)
    assert paths == ["normwise"]
    assert _contains(found, _exact(P, target, k))
    assert float(np.max(found.width)) <= 1e-12  # precise everywhere, absolutely


@pytest.mark.parametrize("seed", range(4))
def test_componentwise_radius_when_normwise_is_too_wide(seed: int, paths: list[str]) -> None:
    P, target = _random_chain(seed)
    k = 25
    with required_precision(1e-9, 1e-300):  # no rounding at all would meet this
        found = kernels.bounded_until_probs(P, np.ones(len(target), dtype=bool), target, k)
    assert paths == ["componentwise"]
    assert _contains(found, _exact(P, target, k))
