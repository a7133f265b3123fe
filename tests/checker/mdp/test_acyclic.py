"""The one certified pass over an acyclic system, against backward induction in rationals."""

from __future__ import annotations

from collections.abc import Callable
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.checker.mdp.counting import counted_evaluations
from tests.checker.mdp.models import mask, mdp_from
from veribattery.checker.mdp import MDP, reach_probability, reach_reward
from veribattery.checker.mdp.acyclic import acyclic_optimum
from veribattery.checker.mdp.system import equations, quotient_classes
from veribattery.checker.mdp.topological import class_levels

#: Probabilities whose doubles are not exact (1/3, 1/7, 1/10) beside exact ones.
SHARES = [Fraction(1, 2), Fraction(1, 3), Fraction(1, 4), Fraction(1, 7), Fraction(1, 10)]

Choice = list[tuple[int, float]]


@st.composite
def acyclic_mdps(draw: st.DrawFn) -> tuple[list[list[Choice]], list[list[float]]]:
    """States 0..n-1 whose choices lead to later states, the goal n or the sink n+1,
    some with a self-loop; per choice a reward."""
    n = draw(st.integers(2, 9))
    states: list[list[Choice]] = []
    rewards: list[list[float]] = []
    for s in range(n):
        choices, costs = [], []
        for _ in range(draw(st.integers(1, 3))):
            stay = draw(st.sampled_from([Fraction(0), Fraction(1, 3), Fraction(1, 2)]))
            later = draw(st.lists(st.integers(s + 1, n + 1), min_size=1, max_size=3,
                                  unique=True))
            shares = [draw(st.sampled_from(SHARES)) for _ in later]
            scale = (1 - stay) / sum(shares)
            choice = [(t, float(share * scale)) for t, share in zip(later, shares, strict=True)]
            if stay:
                choice.append((s, float(stay)))
            choices.append(choice)
            costs.append(float(draw(st.sampled_from([0, 1, 2.5, 10]))))
        states.append(choices)
        rewards.append(costs)
    states += [[[(n, 1.0)]], [[(n + 1, 1.0)]]]
    rewards += [[0.0], [0.0]]
    return states, rewards


def _exact(states: list[list[Choice]], costs: list[list[float]] | None, goal_value: int,
           best: Callable[[list[Fraction]], Fraction],
           fixed: list[int] | None = None) -> list[Fraction]:
    """Backward induction on the stored doubles read exactly: a choice's value is
    ``(reward + sum_t p_t x_t) / sum_t p_t`` over the successors t other than the
    state itself (the self-loop's mass read as the rest, as the engine reads it)."""
    n = len(states) - 2
    x = [Fraction(0)] * (n + 2)
    x[n] = Fraction(goal_value)
    for s in reversed(range(n)):
        images = []
        for a, choice in enumerate(states[s]):
            out = [(t, Fraction(p)) for t, p in choice if t != s]
            reward = Fraction(costs[s][a]) if costs is not None else Fraction(0)
            images.append((reward + sum(p * x[t] for t, p in out)) / sum(p for _, p in out))
        x[s] = images[fixed[s]] if fixed is not None else best(images)
    return x[:n]


def _local(mdp: MDP, choices: np.ndarray) -> list[int]:
    """Global choice indices as each state's own (0, 1, ...)."""
    return [int(c - mdp.row_groups[s]) for s, c in enumerate(choices)]


@settings(max_examples=150, deadline=None)
@given(acyclic_mdps(), st.sampled_from(["min", "max"]), st.booleans())
def test_bounds_hold_the_exact_optimum_and_the_strategy_attains_it(
        model: tuple[list[list[Choice]], list[list[float]]], objective: str,
        rewarded: bool) -> None:
    states, costs = model
    n = len(states) - 2
    mdp = mdp_from(states, labels={"goal": [n]})
    best = max if objective == "max" else min
    if rewarded:
        per_choice = np.array([c for state in costs for c in state])
        result = reach_reward(mdp, per_choice, mask(n + 2, [n, n + 1]),
                              objective=objective)  # type: ignore[arg-type]
        exact = _exact(states, costs, 0, best)
    else:
        result = reach_probability(mdp, mdp.labels["goal"],
                                   objective=objective)  # type: ignore[arg-type]
        exact = _exact(states, None, 1, best)
    lower, upper = result.bounds.lower[:n], result.bounds.upper[:n]
    for k in range(n):
        assert lower[k] <= exact[k] <= upper[k]
    assert result.bounds.precise_states().all()
    chosen = _local(mdp, result.strategy.choices[:n])
    attained = _exact(states, costs if rewarded else None, 0 if rewarded else 1, best, chosen)
    for k in range(n):
        assert abs(float(attained[k] - exact[k])) <= 1e-12 * max(1.0, float(exact[k]))


def test_a_row_into_equal_values_gives_that_value_exactly() -> None:
    # 1/7 + 4/7 + 2/7 in doubles sums to 0.9999999999999999; read in extended precision,
    # both sums are the same and the quotient is 1.
    sevenths = [(1, 1 / 7), (2, 4 / 7), (3, 2 / 7)]
    mdp = mdp_from([[sevenths], [[(1, 1.0)]], [[(2, 1.0)]], [[(3, 1.0)]]],
                   labels={"goal": [1, 2, 3]})
    result = reach_probability(mdp, mdp.labels["goal"], objective="max")
    assert result.values[0] == 1.0 and result.bounds.upper[0] == 1.0


def test_acyclic_systems_take_no_lu_solve(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = counted_evaluations(monkeypatch)
    mdp = mdp_from([
        [[(1, 0.5), (3, 0.5)], [(2, 1.0)]],
        [[(2, 0.25), (1, 0.75)]],
        [[(2, 1.0)]],
        [[(3, 1.0)]],
    ], labels={"goal": [2]})
    result = reach_probability(mdp, mdp.labels["goal"], objective="max")
    assert result.values.tolist() == [1.0, 1.0, 1.0, 0.0]
    low = reach_probability(mdp, mdp.labels["goal"], objective="min")
    assert low.values.tolist() == [0.5, 1.0, 1.0, 0.0]
    assert calls[0] == 0


def test_a_system_with_a_cycle_is_refused() -> None:
    mdp = mdp_from([
        [[(1, 0.5), (2, 0.5)]],
        [[(0, 0.5), (2, 0.5)]],
        [[(2, 1.0)]],
    ])
    system = equations(mdp.transitions, mdp.choice_owner, quotient_classes(mask(3, [0, 1])))
    levels = class_levels(system)
    assert not levels.acyclic
    with pytest.raises(ValueError, match="cycle"):
        acyclic_optimum(system, "max", np.array([1.0]), None, levels,
                        np.array([0, 1]), 1.0)
