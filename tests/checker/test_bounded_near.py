"""Step-bounded until on the states within k steps of the target only (kernels.bounded_until_probs).

States farther than *k* steps have probability exactly 0; the iteration on the
near states must give the values, and intervals, of the iteration on all states.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker import exact_reference as ref
from tests.checker.test_scc_solve import _grid
from veribattery.checker import kernels
from veribattery.checker.kernels import steps


@pytest.mark.parametrize("k", [0, 1, 7, 23])
def test_far_states_are_zero_and_near_ones_exact(k: int) -> None:
    side = 12
    P = _grid(side)
    n = P.shape[0]
    target = np.zeros(n, dtype=bool)
    target[-1] = True
    remain = np.ones(n, dtype=bool)
    remain[side * 5 + 7] = False  # one forbidden state inside the near region
    found = kernels.bounded_until_probs(P, remain, target, k)
    x, y = np.divmod(np.arange(n), side)
    far = (side - 1 - x) + (side - 1 - y) > k  # Manhattan distance to the corner
    assert np.all(found.value[far] == 0) and np.all(found.upper[far] == 0)
    hit = [Fraction(int(t)) for t in target]
    moving = sp.csr_matrix(sp.diags((remain & ~target).astype(float)) @ P)
    exact = ref.step_power(moving, hit, hit, k)
    assert all(Fraction(float(lo)) <= v <= Fraction(float(hi))
               for lo, hi, v in zip(found.lower, found.upper, exact, strict=True))
    assert np.all(found.value[~far & remain] > 0)


def test_near_iteration_matches_the_whole_one_bit_for_bit(monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    P = _grid(20)
    n = P.shape[0]
    target = np.zeros(n, dtype=bool)
    target[[n - 1, n - 20]] = True
    remain = np.ones(n, dtype=bool)
    near = kernels.bounded_until_probs(P, remain, target, 9)
    monkeypatch.setattr(steps, "_within_steps",
                        lambda moving, target, k: np.ones(moving.shape[0], dtype=bool))
    whole = kernels.bounded_until_probs(P, remain, target, 9)
    assert np.array_equal(near.value, whole.value)
    assert np.all(near.lower >= whole.lower) and np.all(near.upper <= whole.upper)


def test_no_target_gives_zero() -> None:
    P = _grid(4)
    none = np.zeros(16, dtype=bool)
    found = kernels.bounded_until_probs(P, np.ones(16, dtype=bool), none, 5)
    assert not found.value.any() and not found.upper.any()
