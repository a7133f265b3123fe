"""Pmin and Pmax of unbounded reachability on hand-solved MDPs."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from tests.checker.mdp import chain_values
from tests.checker.mdp.models import TIED_EXIT, mask, mdp_from
from veribattery.checker.mdp import exact_reach_probability, induced_chain, reach_probability


def test_pmax_leaves_an_end_component_through_its_best_exit() -> None:
    goal = TIED_EXIT.labels["goal"]
    result = reach_probability(TIED_EXIT, goal, objective="max")
    assert result.values == pytest.approx([0.7, 0.7, 1.0, 0.0], rel=1e-12)
    assert np.all(result.lower <= [0.7, 0.7, 1, 0]) and np.all(result.upper >= [0.7, 0.7, 1, 0])
    # State 1 must take its exit, state 0 move to 1: the tie back to 0 is a trap.
    assert result.strategy.choices[:2].tolist() == [0, 3]
    induced = induced_chain(TIED_EXIT, result.strategy).toarray()
    assert chain_values.until(induced, np.ones(4, dtype=bool), goal)[:2] == pytest.approx(
        [0.7, 0.7], rel=1e-12)


def test_pmin_stays_in_the_end_component() -> None:
    result = reach_probability(TIED_EXIT, TIED_EXIT.labels["goal"], objective="min")
    assert result.values.tolist() == [0.0, 0.0, 1.0, 0.0]
    assert result.lower.tolist() == result.upper.tolist()
    assert result.strategy.choices[:2].tolist() == [0, 2]


def test_until_with_a_blocked_state() -> None:
    # 0 -a-> 1 (0.5) or 2 (0.5); 0 -b-> 3; 1 -> goal 4; 2 -> 0 (1/3) or goal (2/3);
    # 3 -> goal. Outside "remain" = {0, 1, 2}: state 3 blocks.
    mdp = mdp_from([
        [[(1, 0.5), (2, 0.5)], [(3, 1)]],
        [[(4, 1)]],
        [[(0, 1 / 3), (4, 2 / 3)]],
        [[(4, 1)]],
        [[(4, 1)]],
    ])
    remain, goal = mask(5, [0, 1, 2]), mask(5, [4])
    high = reach_probability(mdp, goal, objective="max", remain=remain)
    low = reach_probability(mdp, goal, objective="min", remain=remain)
    assert high.values[0] == pytest.approx(1.0) and high.strategy.choices[0] == 0
    # min: b at 0 leads to the blocked state 3: probability 0.
    assert low.values[0] == 0.0 and low.strategy.choices[0] == 1
    everywhere = reach_probability(mdp, goal, objective="min")
    assert everywhere.values[0] == 1.0  # without remain, every path reaches the goal


def test_pmin_chooses_the_smaller_gamble() -> None:
    # x0 = min(0.5 x2 + 0.5, 0.25 + 0.75 x1), x1 = 0.5, x2 = 0.9: exactly 0.625
    mdp = mdp_from([
        [[(2, 0.5), (3, 0.5)], [(3, 0.25), (1, 0.75)]],
        [[(3, 0.5), (4, 0.5)]],
        [[(3, 0.9), (4, 0.1)]],
        [[(3, 1)]],
        [[(4, 1)]],
    ])
    goal = mask(5, [3])
    result = reach_probability(mdp, goal, objective="min")
    assert result.values[:3] == pytest.approx([0.625, 0.5, 0.9], rel=1e-12)
    assert result.strategy.choices[0] == 1
    assert result.lower[0] <= 0.625 <= result.upper[0]
    assert result.bounds.precise_states().all()


def test_ill_conditioned_small_system_is_solved_exactly() -> None:
    """Two states that pass the mass back and forth and leak 1e-13 per step: the
    float certificate cannot reach 1e-9, so the small system is solved in rationals
    and the bounds are the floats either side of the exact value."""
    eps = 1e-13
    mdp = mdp_from([
        [[(1, 1 - eps), (2, eps / 2), (3, eps / 2)], [(2, 0.3), (3, 0.7)]],
        [[(0, 1 - eps), (2, eps / 3), (3, 2 * eps / 3)]],
        [[(2, 1)]], [[(3, 1)]],
    ])
    goal = mask(4, [2])
    result = reach_probability(mdp, goal, objective="max")
    assert result.values[0] == pytest.approx(5 / 12, rel=1e-9)
    assert result.bounds.precise_states().all()
    assert result.strategy.choices[0] == 0
    exact = exact_reach_probability(mdp, goal, objective="max").values[0]
    assert Fraction(result.lower[0]) <= Fraction(int(exact.numerator), int(exact.denominator))
    assert Fraction(int(exact.numerator), int(exact.denominator)) <= Fraction(result.upper[0])


def test_pmax_certified_through_a_long_chain_of_ties() -> None:
    # State i may gamble (0.3 to the goal, 0.7 to a sink) or pass to i + 1, whose value
    # is the same 0.3: every state ties two rows that spread their mass differently.
    # The strategy's margin covers only the gamble; the passing rows need the margin of
    # the tied rows, else the upper certificate falls back to interval iteration, which
    # cannot cross 3,000 states in its sweeps (too many for the exact fallback, too).
    n = 3_000
    goal, sink = n, n + 1
    gamble = [(goal, 0.3), (sink, 0.7)]
    states = [[gamble, [(i + 1, 1.0)]] for i in range(n - 1)] + [[gamble]]
    mdp = mdp_from([*states, [[(goal, 1.0)]], [[(sink, 1.0)]]], labels={"goal": [goal]})
    result = reach_probability(mdp, mdp.labels["goal"], objective="max")
    assert result.bounds.precise_states().all()
    assert np.all(result.lower[:n] <= 0.3) and np.all(result.upper[:n] >= 0.3)
    assert result.values[:n] == pytest.approx(np.full(n, 0.3), rel=1e-12)
