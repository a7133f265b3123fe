"""Step-bounded operators on hand-solved MDPs, and their step-dependent strategies."""

from __future__ import annotations

import numpy as np
import pytest

from tests.checker.mdp.models import mask, mdp_from
from veribattery.checker.mdp import (
    StepStrategy,
    bounded_reach_probability,
    cumulative_reward,
    instantaneous_reward,
    interval_reach_probability,
    later_reach_probability,
    next_probability,
)

# 0: a -> 1, b -> goal 2 (1/2) or trap 3 (1/2); 1: -> goal (0.9) or stays (0.1).
RACE = mdp_from([
    [[(1, 1)], [(2, 0.5), (3, 0.5)]],
    [[(2, 0.9), (1, 0.1)]],
    [[(2, 1)]],
    [[(3, 1)]],
], rewards=[[1, 0], [2], [0], [0]])
GOAL = mask(4, [2])


def test_the_best_first_move_depends_on_the_steps_left() -> None:
    one = bounded_reach_probability(RACE, GOAL, 1, objective="max")
    two = bounded_reach_probability(RACE, GOAL, 2, objective="max")
    assert one.values[0] == 0.5 and two.values[0] == pytest.approx(0.9, rel=1e-15)
    three = bounded_reach_probability(RACE, GOAL, 3, objective="max")
    assert three.values[0] == pytest.approx(0.99, rel=1e-15)
    assert three.lower[0] <= 0.99 <= three.upper[0]
    strategy = two.strategy
    assert isinstance(strategy, StepStrategy)
    assert strategy.at(0).choices[0] == 0  # two steps left: a
    assert strategy.at(1).choices[0] == 1  # one step left: b
    with pytest.raises(ValueError, match="bounded"):
        strategy.at(2)


def test_min_and_next() -> None:
    assert bounded_reach_probability(RACE, GOAL, 5, objective="min").values[0] == 0.5
    assert next_probability(RACE, GOAL, objective="max").values.tolist() == [0.5, 0.9, 1, 0]
    assert next_probability(RACE, GOAL, objective="min").values.tolist() == [0, 0.9, 1, 0]
    assert bounded_reach_probability(RACE, GOAL, 0, objective="max").values.tolist() == [
        0, 0, 1, 0]


def test_remain_blocks() -> None:
    found = bounded_reach_probability(RACE, GOAL, 3, objective="max", remain=mask(4, [0]))
    assert found.values[0] == 0.5  # 1 may not be passed through


def test_lower_and_interval_bounds() -> None:
    # U>=1 from 0: leave 0 first; Pmax [F>=1 goal] = Pmax [F goal] from the successors:
    # a gives 1 (1 reaches the goal almost surely), so 1.
    later = later_reach_probability(RACE, GOAL, 1, objective="max")
    assert later.values[0] == pytest.approx(1.0)
    window = interval_reach_probability(RACE, GOAL, 1, 2, objective="max")
    # step 1 in 0 -> then within 1 more step: via a, 0.9; via b: 0.5.
    assert window.values[0] == pytest.approx(0.9, rel=1e-15)
    assert window.strategy.at(0).choices[0] == 0


def test_cumulative_and_instantaneous() -> None:
    rewards = RACE.rewards[0].per_choice(RACE)
    # Rmax [C<=2] from 0: a (1) then 1's reward 2: 3. Rmin: b then 0.
    assert cumulative_reward(RACE, rewards, 2, objective="max").values[0] == 3
    assert cumulative_reward(RACE, rewards, 2, objective="min").values[0] == 0
    # I=1 with state rewards (1 in state 1): max 1 (a), min 0 (b).
    state = mask(4, [1]).astype(float)
    assert instantaneous_reward(RACE, state, 1, objective="max").values[0] == 1
    assert instantaneous_reward(RACE, state, 1, objective="min").values[0] == 0
    assert instantaneous_reward(RACE, state, 2, objective="max").values[0] == pytest.approx(0.1)


def test_exact_inputs_give_exact_bounds() -> None:
    found = next_probability(RACE, GOAL, objective="max")
    assert found.lower.tolist() == found.upper.tolist() == [0.5, 0.9, 1, 0]


def test_a_goal_out_of_reach_is_exactly_zero() -> None:
    # Five steps to the goal: within four it is out of reach, and the bounds say so
    # exactly (those states are kept out of the rounds), not [0, a few ulps of 2**-900]
    # (`0 +- 2.8e-270` at 80 columns, and `P>0` on it taken to exact arithmetic).
    chain = mdp_from([[[(i + 1, 0.5), (i, 0.5)], [(i + 1, 0.25), (i, 0.75)]] for i in range(5)]
                     + [[[(5, 1)]], [[(6, 1)]]])  # (6: a sink that never reaches the goal)
    goal = mask(7, [5])
    for objective in ("min", "max"):
        for steps in (2, 4, 7):
            found = bounded_reach_probability(chain, goal, steps, objective=objective)
            far = max(5 - steps, 0)  # (state i is 5 - i steps from the goal)
            assert found.lower[:far].tolist() == found.upper[:far].tolist() == [0.0] * far
            assert np.all(found.lower[far:5] > 0.0)
            assert found.lower[6] == found.upper[6] == 0.0  # (the sink: never)
