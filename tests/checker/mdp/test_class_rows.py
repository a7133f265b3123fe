"""ClassRows takes the best of each class's rows as reduceat does, float for float."""

from __future__ import annotations

import numpy as np
import pytest

from veribattery.checker.mdp.system import FEW_ROWS, ClassRows


@pytest.mark.parametrize("objective", ["max", "min"])
def test_best_is_reduceat_bit_for_bit(objective: str) -> None:
    rng = np.random.default_rng(7)
    # Classes of 1 to 3 rows mostly, some above FEW_ROWS (taken by reduceat).
    sizes = np.concatenate([rng.integers(1, 4, 500), rng.integers(FEW_ROWS + 1, 30, 20)])
    rng.shuffle(sizes)
    groups = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    values = rng.random(int(groups[-1])) * 10.0 ** rng.integers(-300, 300, int(groups[-1]))
    values[rng.random(values.size) < 0.1] = 0.0  # ties at exact zeros
    values[rng.random(values.size) < 0.05] = np.inf
    reduce = np.maximum if objective == "max" else np.minimum
    expected = reduce.reduceat(values, groups[:-1])
    got = ClassRows.of(groups).best(values, objective)  # type: ignore[arg-type]
    assert got.view(np.int64).tolist() == expected.view(np.int64).tolist()


def test_best_rows_of_integers() -> None:
    groups = np.array([0, 1, 4, 14], dtype=np.int64)  # one class of 10 rows > FEW_ROWS
    rows = np.array([5, 9, 2, 7, 3, 3, 8, 1, 6, 4, 9, 9, 2, 5], dtype=np.int64)
    assert ClassRows.of(groups).best(rows, "min").tolist() == [5, 2, 1]
    assert ClassRows.of(groups).best(rows, "max").tolist() == [5, 9, 9]
