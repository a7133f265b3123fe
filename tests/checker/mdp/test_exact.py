"""The exact engine: rationals on hand-solved MDPs, optimality verified exactly."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from gmpy2 import mpq

from tests.checker.mdp.models import (
    TIED_EXIT,
    TIED_EXIT_CHOICES,
    ZERO_CYCLE,
    entries_of,
    mask,
    mdp_from,
)
from veribattery.checker.mdp import (
    exact_probabilities,
    exact_reach_probability,
    exact_reach_reward,
    exact_total_reward,
)


def test_pmax_exact_with_decimal_probabilities() -> None:
    found = exact_reach_probability(TIED_EXIT, TIED_EXIT.labels["goal"], objective="max",
                                    probabilities=entries_of(TIED_EXIT_CHOICES))
    assert found.values.tolist() == [mpq(7, 10), mpq(7, 10), 1, 0]
    assert found.strategy.choices[:2].tolist() == [0, 3]


def test_the_float_entries_read_exactly_differ() -> None:
    """Without exact probabilities the stored doubles are read as the rationals they are,
    and -- as on the DTMC side -- the mass a choice keeps in its (collapsed) class is
    1 minus the mass it sends out: the exit 0.7 + 0.3 sums to slightly more than 1."""
    found = exact_reach_probability(TIED_EXIT, TIED_EXIT.labels["goal"], objective="max")
    assert found.values[0] == mpq(0.7) / (mpq(0.7) + mpq(0.3))
    assert found.values[0] != mpq(7, 10) and mpq(0.7) + mpq(0.3) != 1
    assert exact_probabilities(TIED_EXIT)[1] == mpq(0.4)


def test_rmin_exact_on_the_zero_cycle() -> None:
    rewards = np.array([mpq(int(r)) for r in ZERO_CYCLE.rewards[0].per_choice(ZERO_CYCLE)],
                       dtype=object)
    found = exact_reach_reward(ZERO_CYCLE, rewards, ZERO_CYCLE.labels["goal"], objective="min")
    assert found.infinite.tolist() == [False, False, False, True, False]
    assert [found.values[s] for s in (0, 1, 2, 4)] == [5, 5, 0, 10]


def test_exact_value_with_a_repeating_fraction() -> None:
    # x0 = max(1/3 + 1/3 x0, 1/2): a gives x0 = 1/2 too -- a tie, b is the proper exit;
    # with rewards (a: 1, b: 0): Rmax [F goal] = x with x = 1 + x/3 -> 3/2.
    choices = [[[(2, Fraction(1, 3)), (0, Fraction(1, 3)), (1, Fraction(1, 3))],
                [(2, Fraction(1, 2)), (1, Fraction(1, 2))]],
               [[(1, 1)]], [[(2, 1)]]]
    mdp = mdp_from(choices)
    entries = entries_of(choices)
    found = exact_reach_probability(mdp, mask(3, [2]), objective="max", probabilities=entries)
    assert found.values[0] == mpq(1, 2)
    rewards = np.array([mpq(1), mpq(0), mpq(0), mpq(0)], dtype=object)
    reward = exact_reach_reward(mdp, rewards, mask(3, [0, 1, 2]) & ~mask(3, [0]),
                                objective="max", probabilities=entries)
    assert reward.values[0] == mpq(3, 2)
    total = exact_total_reward(mdp, rewards, objective="max", probabilities=entries)
    assert total.values[0] == mpq(3, 2) and not total.infinite.any()
