"""ChoiceLevels: the level layout gives reduceat's optima, the first best choices and the
products of the stored layout, float for float; step-bounded results do not change."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from veribattery.checker.mdp import (
    MDP,
    bounded_reach_probability,
    cumulative_reward,
    instantaneous_reward,
    stepped,
)
from veribattery.checker.mdp.levels import DEEPEST, ChoiceLevels


def random_mdp(seed: int, deep: bool = False) -> MDP:
    """States of 1 to 5 choices (one of DEEPEST + 3 if *deep*), 1 to 4 successors each,
    probabilities of a few bits so that ties between choices are common."""
    rng = np.random.default_rng(seed)
    n = 300
    sizes = rng.integers(1, 6, n)
    if deep:
        sizes[rng.integers(n)] = DEEPEST + 3
    groups = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    rows, cols, data = [], [], []
    for row in range(int(groups[-1])):
        successors = rng.choice(n, size=int(rng.integers(1, 5)), replace=False)
        weights = rng.integers(1, 4, successors.size).astype(float)
        rows += [row] * successors.size
        cols += successors.tolist()
        data += (weights / weights.sum()).tolist()
    matrix = sp.csr_matrix((data, (rows, cols)), shape=(int(groups[-1]), n))
    return MDP(matrix, groups, np.array([0]))


def bits(values: np.ndarray) -> list[int]:
    return np.asarray(values, dtype=np.float64).view(np.int64).tolist()


@pytest.mark.parametrize("deep", [False, True])
@pytest.mark.parametrize("reduce", [np.maximum, np.minimum])
def test_optimum_and_first_best_are_reduceats(deep: bool, reduce: np.ufunc) -> None:
    mdp = random_mdp(3, deep)
    levels = ChoiceLevels.of(mdp)
    assert levels.leveled is not deep
    rng = np.random.default_rng(5)
    images = rng.integers(0, 4, mdp.num_choices) * 10.0 ** rng.integers(-300, 300, 1)
    images[rng.random(images.size) < 0.05] = np.inf
    expected = reduce.reduceat(images, mdp.row_groups[:-1])
    laid = levels.choices(images)
    best = levels.optimum(laid, reduce)
    assert bits(levels.restored(best)) == bits(expected)
    hits = images == expected[mdp.choice_owner]
    first = np.minimum.reduceat(np.where(hits, np.arange(images.size), images.size),
                                mdp.row_groups[:-1])
    assert levels.chosen(levels.first_attaining(laid, best)).tolist() == first.tolist()


@pytest.mark.parametrize("deep", [False, True])
def test_products_are_the_stored_layout_s_bit_for_bit(deep: bool) -> None:
    mdp = random_mdp(4, deep)
    levels = ChoiceLevels.of(mdp)
    x = np.random.default_rng(6).random(mdp.num_states)
    assert bits(levels.matrix @ levels.states(x)) == bits(levels.choices(mdp.transitions @ x))
    assert levels.restored(levels.states(x)).tolist() == x.tolist()


def test_a_nan_optimum_takes_the_first_choice() -> None:
    mdp = random_mdp(8)
    levels = ChoiceLevels.of(mdp)
    images = np.full(mdp.num_choices, np.nan)
    best = levels.optimum(levels.choices(images), np.maximum)
    chosen = levels.chosen(levels.first_attaining(levels.choices(images), best))
    assert chosen.tolist() == mdp.row_groups[:-1].tolist()


@pytest.mark.parametrize("objective", ["min", "max"])
def test_step_bounded_results_and_strategies_do_not_depend_on_the_layout(
        objective: str, monkeypatch: pytest.MonkeyPatch) -> None:
    mdp = random_mdp(11)
    target = np.zeros(mdp.num_states, dtype=bool)
    target[:20] = True
    rewards = np.random.default_rng(12).integers(0, 5, mdp.num_choices).astype(float)

    def results() -> list[tuple[list[int], list[int], list[list[int]]]]:
        found = [bounded_reach_probability(mdp, target, 25, objective=objective),
                 cumulative_reward(mdp, rewards, 25, objective=objective),
                 instantaneous_reward(mdp, rewards[mdp.row_groups[:-1]], 25,
                                      objective=objective)]
        return [(bits(r.lower), bits(r.upper),
                 [r.strategy.at(step).choices.tolist() for step in (0, 12, 24)])
                for r in found]

    leveled = results()
    monkeypatch.setattr(stepped.ChoiceLevels, "of", ChoiceLevels.grouped)
    assert results() == leveled
