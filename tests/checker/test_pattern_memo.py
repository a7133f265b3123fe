"""The 0/1 pre-pass is shared between matrices with the same sparsity pattern."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from tests.checker.chains import matrix
from veribattery.checker import Workspace, kernels
from veribattery.checker.kernels import systems


def _chain(p: float) -> sp.csr_matrix:
    return matrix({0: {1: p, 2: 1 - p}, 1: {0: 0.5, 3: 0.5}, 2: {2: 1.0}, 3: {3: 1.0}}, 4)


def test_same_pattern_shares_prepass_and_values_stay_independent() -> None:
    target = np.array([False, False, False, True])
    everywhere = np.ones(4, dtype=bool)
    first, second = _chain(0.25), _chain(0.75)
    workspace = Workspace()
    a = kernels.until_probs(first, everywhere, target, workspace=workspace)
    masks = systems._pattern_masks(first, workspace)
    assert masks and systems._pattern_masks(second, workspace) is masks
    b = kernels.until_probs(second, everywhere, target, workspace=workspace)
    # x0 = p x1, x1 = 1/2 x0 + 1/2  =>  x0 = p / (2 - p)
    assert a.value[0] == 0.25 / 1.75 and abs(b.value[0] - 0.75 / 1.25) <= 1e-16
    assert a.lower[0] <= 0.25 / 1.75 <= a.upper[0]


def test_different_pattern_gets_its_own_prepass() -> None:
    other = matrix({0: {1: 1.0}, 1: {0: 0.5, 3: 0.5}, 2: {2: 1.0}, 3: {3: 1.0}}, 4)
    workspace = Workspace()
    same = _chain(0.5)
    assert systems._pattern_masks(other, workspace) is not systems._pattern_masks(same, workspace)
    target = np.array([False, False, False, True])
    found = kernels.until_probs(other, np.ones(4, dtype=bool), target, workspace=workspace)
    assert found.value[0] == 1.0  # prob1 of this pattern, not the other's
