"""Multi-objective queries: hand-solved trade-offs and agreement with single objectives."""

from __future__ import annotations

import math
import random

import pytest

from tests.checker.mdp.models import mask, mdp_from
from veribattery.checker.mdp import (
    Constraint,
    Reach,
    Total,
    multi_achievable,
    multi_optimum,
    reach_probability,
    total_reward,
)

# 0: a -> A (2) free; b -> B (3) at reward 1; c -> A or B (1/2 each) at reward 2.
# 1 is unreachable. A and B absorb.
FORK = mdp_from([[[(2, 1)], [(3, 1)], [(2, 0.5), (3, 0.5)]], [[(1, 1)]], [[(2, 1)]], [[(3, 1)]]],
                rewards=[[0, 1, 2], [0], [0], [0]])
A, B = mask(4, [2]), mask(4, [3])
COST = FORK.rewards[0].per_choice(FORK)


def test_randomisation_is_needed_for_both_targets() -> None:
    both = [Constraint(Reach(A), ">=", 0.5), Constraint(Reach(B), ">=", 0.5)]
    assert multi_achievable(FORK, both).achievable
    # mixing a and b (0.5 each) costs 0.5; c costs 2: nothing meets a budget of 0.4
    assert not multi_achievable(FORK, [*both, Constraint(Total(COST), "<=", 0.4)]).achievable
    assert multi_achievable(FORK, [*both, Constraint(Total(COST), "<=", 0.5)]).achievable


def test_numerical_queries() -> None:
    best = multi_optimum(FORK, Reach(B), "max", [Constraint(Total(COST), "<=", 0.4)])
    assert best.value == pytest.approx(0.4, abs=1e-9)
    cheapest = multi_optimum(FORK, Total(COST), "min", [Constraint(Reach(B), ">=", 0.7)])
    assert cheapest.value == pytest.approx(0.7, abs=1e-9)
    assert multi_optimum(FORK, Reach(A), "min", [Constraint(Reach(B), "<=", 0.25)]).value == (
        pytest.approx(0.75, abs=1e-9))


def test_targets_are_remembered_in_the_product() -> None:
    # 0 -> 1 (target T1) -> choice: back to 0... no: 1 -> 2 (T2) or 1 -> 3 (neither);
    # T1 is passed on every path, so P(F T1) = 1 whatever is chosen.
    mdp = mdp_from([[[(1, 1)]], [[(2, 1)], [(3, 1)]], [[(2, 1)]], [[(3, 1)]]])
    t1, t2 = mask(4, [1]), mask(4, [2])
    found = multi_optimum(mdp, Reach(t2), "max", [Constraint(Reach(t1), ">=", 1.0)])
    assert found.value == pytest.approx(1.0)
    assert not multi_achievable(mdp, [Constraint(Reach(t1), "<=", 0.5)]).achievable


def test_maximised_reward_an_end_component_makes_unbounded() -> None:
    # 0 may loop paying 1 and leave to 1 (free, absorbing) whenever it likes.
    mdp = mdp_from([[[(0, 1)], [(1, 1)]], [[(1, 1)]]], rewards=[[1, 0], [0]])
    rewards = mdp.rewards[0].per_choice(mdp)
    assert multi_optimum(mdp, Total(rewards), "max", []).value == math.inf
    assert multi_optimum(mdp, Total(rewards), "min", []).value == pytest.approx(0.0)


@pytest.mark.parametrize("seed", range(12), ids=lambda s: f"seed{s}")
def test_single_objectives_agree_with_the_kernels(seed: int) -> None:
    pytest.importorskip("stormpy")
    from tests.checker.mdp.storm_mdp import build, random_model

    rng = random.Random(seed)
    mdp = build(random_model(rng, modules=rng.choice([2, 3]))).mdp
    if mdp.initial.size != 1:
        pytest.skip("several initial states")
    start, goal = int(mdp.initial[0]), mdp.labels["goal"]
    rewards = mdp.rewards[0].per_choice(mdp)
    for objective in ("min", "max"):
        alone = reach_probability(mdp, goal, objective=objective).values[start]
        assert multi_optimum(mdp, Reach(goal), objective, []).value == pytest.approx(
            alone, abs=1e-7)
    least = total_reward(mdp, rewards, objective="min").values[start]
    found = multi_optimum(mdp, Total(rewards), "min", [])
    if math.isinf(least):
        assert not found.achievable
    else:
        assert found.value == pytest.approx(least, rel=1e-7, abs=1e-9)
