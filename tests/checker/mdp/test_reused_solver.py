"""A strategy's solver carried to a system restricted to some rows gives the same values."""

from __future__ import annotations

import numpy as np
import pytest

from tests.checker.mdp.test_bellman_image import _random_system
from veribattery.checker.mdp.solve import evaluate


@pytest.mark.parametrize("seed", range(6))
def test_restricted_system_reuses_the_solver(seed: int) -> None:
    rng = np.random.default_rng(seed)
    system, known = _random_system(rng, 200)
    rows = system.groups[:-1].copy()  # each class's first row reaches a known state
    found = evaluate(system, rows, known, None)
    assert found is not None
    keep = rng.random(system.choices.size) < 0.5
    keep[rows] = True
    sub = system.restricted(keep)
    start = (np.cumsum(keep) - 1)[rows]
    reward = rng.random(sub.choices.size)
    fresh = evaluate(sub, start, np.zeros(known.size), reward)
    reused = evaluate(sub, start, np.zeros(known.size), reward, found.solver)
    assert fresh is not None and reused is not None
    assert reused.solver is found.solver
    assert reused.values.view(np.int64).tolist() == fresh.values.view(np.int64).tolist()
    assert np.all(np.isfinite(fresh.values)) and np.any(fresh.values > 0)
