"""Rmin and Rmax of reachability and total rewards on hand-solved MDPs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.checker.mdp.models import ZERO_CYCLE, mask, mdp_from
from veribattery.checker.mdp import reach_reward, total_reward


def _rewards(mdp):  # type: ignore[no-untyped-def]
    return mdp.rewards[0].per_choice(mdp)


def test_rmin_through_a_zero_reward_cycle_is_not_zero() -> None:
    goal = ZERO_CYCLE.labels["goal"]
    result = reach_reward(ZERO_CYCLE, _rewards(ZERO_CYCLE), goal, objective="min")
    assert result.values.tolist() == pytest.approx([5, 5, 0, math.inf, 10], rel=1e-12)
    assert result.lower[0] <= 5 <= result.upper[0]
    assert result.upper[3] == math.inf and result.lower[3] == math.inf
    # 0 moves to 1, 1 leaves to the goal, 4 takes the sure way
    assert result.strategy.choices[[0, 1, 4]].tolist() == [0, 2, 6]


def test_value_iteration_from_zero_would_be_fooled() -> None:
    """Naive value iteration from 0 converges to the cycle's fixed point 0."""
    mdp, goal = ZERO_CYCLE, ZERO_CYCLE.labels["goal"]
    rewards = _rewards(mdp)
    x = np.zeros(mdp.num_states)
    for _ in range(200):
        images = rewards + mdp.transitions @ x
        x = np.where(goal, 0.0, np.minimum.reduceat(images, mdp.row_groups[:-1]))
    assert x[:2].tolist() == [0.0, 0.0]
    result = reach_reward(mdp, rewards, goal, objective="min")
    assert result.lower[:2].tolist() == pytest.approx([5, 5], rel=1e-9)


def test_rmax_is_infinite_where_the_goal_can_be_missed() -> None:
    goal = ZERO_CYCLE.labels["goal"]
    result = reach_reward(ZERO_CYCLE, _rewards(ZERO_CYCLE), goal, objective="max")
    # 0 and 1 can cycle forever (probability 0 of the goal); 4 can gamble into 3.
    assert result.values.tolist() == [math.inf, math.inf, 0, math.inf, math.inf]
    assert result.strategy.choices[4] == 5  # the gamble


def test_rmax_reach_finite() -> None:
    # 0 -a-> 1 at reward 1 or -b-> goal at reward 3; 1 -> goal (1/2) or 0 (1/2), reward 2.
    # x0 = max(1 + x1, 3), x1 = 2 + x0 / 2: with a, x0 = 3 + x0 / 2 -> 6.
    mdp = mdp_from([
        [[(1, 1)], [(2, 1)]],
        [[(2, 0.5), (0, 0.5)]],
        [[(2, 1)]],
    ], rewards=[[1, 3], [2], [0]])
    result = reach_reward(mdp, _rewards(mdp), mask(3, [2]), objective="max")
    assert result.values.tolist() == pytest.approx([6, 5, 0], rel=1e-12)
    assert result.strategy.choices[0] == 0
    low = reach_reward(mdp, _rewards(mdp), mask(3, [2]), objective="min")
    assert low.values.tolist() == pytest.approx([3, 3.5, 0], rel=1e-12)


def test_total_reward_with_end_components() -> None:
    # 0: a -> 1 (reward 1), b -> 2 (reward 4). 1: self-loop at reward 0 or -> 3 at
    # reward 2. 2: self-loop paying 1 (infinite for Rmax), or -> 3 at reward 0.
    # 3: absorbing, reward 0.
    mdp = mdp_from([
        [[(1, 1)], [(2, 1)]],
        [[(1, 1)], [(3, 1)]],
        [[(2, 1)], [(3, 1)]],
        [[(3, 1)]],
    ], rewards=[[1, 4], [0, 2], [1, 0], [0]])
    low = total_reward(mdp, _rewards(mdp), objective="min")
    high = total_reward(mdp, _rewards(mdp), objective="max")
    # Rmin: 1 rests in its zero-reward loop (0), so 0 pays 1 to get there.
    assert low.values.tolist() == pytest.approx([1, 0, 0, 0], rel=1e-12)
    assert low.lower[0] <= 1 <= low.upper[0]
    assert low.lower[1:].tolist() == low.upper[1:].tolist() == [0, 0, 0]  # exact zeros
    assert high.values.tolist() == [math.inf, 2, math.inf, 0]
    assert high.strategy.choices[1] == 3  # leaves the zero loop to collect 2
    assert high.strategy.choices[2] == 4  # keeps paying


def test_rmin_total_is_infinite_without_a_free_end_component() -> None:
    # The only end component pays 1 per step.
    mdp = mdp_from([[[(1, 1)]], [[(1, 1)]]], rewards=[[0], [1]])
    assert total_reward(mdp, _rewards(mdp), objective="min").values.tolist() == [
        math.inf, math.inf]


def test_negative_rewards_are_refused() -> None:
    mdp = mdp_from([[[(0, 1)]]], rewards=[[-1]])
    with pytest.raises(ValueError, match="nonnegative"):
        total_reward(mdp, _rewards(mdp), objective="min")
