"""Step-bounded rounds with a priori bounds (``plain_rounds``): the certified bounds
enclose the exact optimum, computed here in rationals by the same recursion on the
stored doubles, and where a value would underflow the rounds carry their radius."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from tests.checker.mdp.models import mask, mdp_from
from veribattery.checker.mdp import bounded_reach_probability, cumulative_reward

Model = list[list[list[tuple[int, float]]]]


def _random_model(seed: int, n: int = 9) -> tuple[Model, list[list[float]]]:
    """Per state 1-3 choices of 1-3 successors with random probabilities (state n-1 a
    goal, n-2 a sink), and a random reward per choice."""
    rng = np.random.default_rng(seed)
    states: Model = []
    rewards: list[list[float]] = []
    for _ in range(n - 2):
        choices = []
        for _ in range(int(rng.integers(1, 4))):
            successors = rng.choice(n, size=int(rng.integers(1, 4)), replace=False)
            weights = rng.random(successors.size) + 0.05
            probabilities = (weights / weights.sum()).tolist()
            choices.append(list(zip(successors.tolist(), probabilities, strict=True)))
        states.append(choices)
        rewards.append(rng.random(len(choices)).round(3).tolist())
    states += [[[(n - 2, 1.0)]], [[(n - 1, 1.0)]]]
    rewards += [[0.0], [0.0]]
    return states, rewards


def _exact(states: Model, rewards: list[list[float]] | None, goal: set[int], steps: int,
           objective: str) -> list[Fraction]:
    """The optimum after *steps* rounds in rationals: a reward's ``C<=k`` (*rewards*), or
    the probability of reaching *goal* within *steps* (None)."""
    pick = max if objective == "max" else min
    x = [Fraction(int(s in goal and rewards is None)) for s in range(len(states))]
    for _ in range(steps):
        x = [x[s] if rewards is None and s in goal else pick(
            sum((Fraction(p) * x[t] for t, p in choice), Fraction(0))
            + (Fraction(rewards[s][a]) if rewards is not None else 0)
            for a, choice in enumerate(choices)) for s, choices in enumerate(states)]
    return x


def _enclosed(found, exact: list[Fraction]) -> None:
    for s, value in enumerate(exact):
        assert Fraction(found.lower[s]) <= value <= Fraction(found.upper[s]), s


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("objective", ["min", "max"])
def test_bounded_reach_and_cumulative_reward_enclose_the_exact_optimum(
        seed: int, objective: str) -> None:
    states, rewards = _random_model(seed)
    model = mdp_from(states, rewards=rewards)
    goal = mask(len(states), [len(states) - 1])
    for steps in (2, 7, 40):
        reach = bounded_reach_probability(model, goal, steps, objective=objective)
        _enclosed(reach, _exact(states, None, {len(states) - 1}, steps, objective))
        gathered = cumulative_reward(model, model.rewards[0].choice, steps,
                                     objective=objective)
        _enclosed(gathered, _exact(states, rewards, set(), steps, objective))
        # (a priori: some 2 k g_T wide, relative, far inside 1e-9; the radius carried
        # row by row is wider)
        width = gathered.upper - gathered.lower
        assert np.all(width <= 4 * steps * 4 * 2.0**-53 * gathered.values + 1e-300)


def test_a_value_that_would_underflow_carries_its_radius() -> None:
    # 0 -> 1..4 with some 1e-160 each, else stays; each of 1..4 -> goal with some
    # 1e-160, else stays: in the second round state 0 sums four subnormal products, whose
    # rounding (up to half a subnormal's ulp each) relative bounds do not cover.
    out = [7.234897555375005e-161, 8.766831143422979e-161, 7.130033010530404e-161,
           1.0172977047909026e-160]
    on = [1.3959287666420287e-161, 6.285892632600216e-161, 5.593358828854037e-161,
          1.6234957914987561e-161]
    states: Model = [[[(i + 1, p) for i, p in enumerate(out)] + [(0, 1 - sum(out))]]]
    states += [[[(5, q), (i + 1, 1 - q)]] for i, q in enumerate(on)] + [[[(5, 1.0)]]]
    model = mdp_from(states)
    for steps in (2, 3):
        found = bounded_reach_probability(model, mask(6, [5]), steps, objective="max")
        _enclosed(found, _exact(states, None, {5}, steps, "max"))


def test_the_rounds_report_their_progress() -> None:
    states, rewards = _random_model(3)
    model = mdp_from(states, rewards=rewards)
    told: list[tuple[int, int, str]] = []
    cumulative_reward(model, model.rewards[0].choice, 30, objective="max",
                      progress=lambda *seen: told.append(seen))
    assert told == [(done, 30, "steps") for done in range(1, 31)]
    told.clear()  # (a value that would underflow: the rounds run again with the radius)
    tiny = [[[(1, 1e-160), (0, 1 - 1e-160)]], [[(2, 1e-160), (1, 1 - 1e-160)]], [[(2, 1.0)]]]
    bounded_reach_probability(mdp_from(tiny), mask(3, [2]), 4, objective="max",
                              progress=lambda *seen: told.append(seen))
    assert told == [(1, 4, "steps")] + [(done, 4, "steps") for done in range(1, 5)]
