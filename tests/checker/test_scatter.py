"""``M^T x`` at the cost of x's nonzeros gives the floats of the full transposed product."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from veribattery.checker.linalg import TransposedProduct
from veribattery.checker.linalg.scatter import SPARSE_SHARE


def _full(M: sp.csr_matrix, x: np.ndarray) -> np.ndarray:
    return np.asarray(sp.csr_matrix(M.T) @ x)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("share", [0.0, 0.002, SPARSE_SHARE / 2, 0.5, 1.0])
def test_the_same_floats_as_the_transposed_matrix(seed: int, share: float) -> None:
    rng = np.random.default_rng(seed)
    rows, columns = 3000, 2500
    M = sp.random(rows, columns, density=0.004, format="csr", random_state=seed,
                  data_rvs=lambda k: rng.random(k) / 3)
    x = np.zeros(rows)
    chosen = rng.choice(rows, int(share * rows), replace=False)
    x[chosen] = rng.random(chosen.size) * 10.0 ** rng.integers(-300, 3, chosen.size)
    x[chosen[: chosen.size // 10]] *= -1  # signs do not matter
    x[rng.choice(rows, 20)] = -0.0
    assert np.array_equal(TransposedProduct(M)(x), _full(M, x))


def test_a_hand_sized_product() -> None:
    M = sp.csr_matrix(np.array([[0.5, 0.5, 0.0], [0.0, 0.25, 0.75], [1.0, 0.0, 0.0]]))
    x = np.array([0.0, 0.4, 0.0])
    assert TransposedProduct(M)(x).tolist() == [0.0, 0.1, 0.30000000000000004]
    assert TransposedProduct(M)(np.zeros(3)).tolist() == [0.0, 0.0, 0.0]
