"""The MDP kernels against Storm on random PRISM ``mdp`` models.

Storm builds each model; its own sparse matrix, row groups, labels and rewards
become an :class:`MDP` (``storm_mdp.to_mdp``), so states match one to one. Storm's
*exact* engine gives the reference values: with dyadic probabilities the float
model is the exact one, so every reference value must lie inside the certified
interval; the point value must agree to 1e-9, and the strategy's induced chain
(solved independently, ``chain_values``) must attain the optimum. Models with
probabilities like 1/3 and 1/10 are compared to the same tolerance, and in the
exact engine, with Storm's rationals as input, value for value.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from fractions import Fraction

import numpy as np
import pytest

stormpy = pytest.importorskip("stormpy")

from tests.checker.mdp import chain_values  # noqa: E402
from tests.checker.mdp.storm_mdp import (  # noqa: E402
    Built,
    build,
    exact_entries,
    exact_rewards,
    random_model,
    storm_values,
)
from veribattery.checker.mdp import (  # noqa: E402
    MdpResult,
    bounded_reach_probability,
    cumulative_reward,
    exact_reach_probability,
    exact_reach_reward,
    exact_total_reward,
    instantaneous_reward,
    interval_reach_probability,
    next_probability,
    reach_probability,
    reach_reward,
    total_reward,
)

Check = Callable[[Built], MdpResult]
Induced = Callable[[np.ndarray, np.ndarray, Built], np.ndarray]


def _model(seed: int, *, dyadic: bool) -> Built:
    rng = random.Random(seed)
    return build(random_model(rng, modules=rng.choice([2, 3]), dyadic=dyadic))


def _unbounded() -> list[tuple[str, Check, Induced]]:
    """(Storm formula, our kernel, the value of a strategy's induced chain)."""
    cases: list[tuple[str, Check, Induced]] = []
    for o in ("min", "max"):
        cases += [
            (f'P{o}=? [F "goal"]',
             lambda b, o=o: reach_probability(b.mdp, b.mdp.labels["goal"], objective=o),
             lambda P, r, b: chain_values.until(P, np.ones(len(P), dtype=bool),
                                                b.mdp.labels["goal"])),
            (f'P{o}=? ["safe" U "goal"]',
             lambda b, o=o: reach_probability(b.mdp, b.mdp.labels["goal"], objective=o,
                                              remain=b.mdp.labels["safe"]),
             lambda P, r, b: chain_values.until(P, b.mdp.labels["safe"], b.mdp.labels["goal"])),
            (f'R{o}=? [F "goal"]',
             lambda b, o=o: reach_reward(b.mdp, _rewards(b), b.mdp.labels["goal"], objective=o),
             lambda P, r, b: chain_values.reach_reward(P, r, b.mdp.labels["goal"])),
            (f'R{o}=? [C]',
             lambda b, o=o: total_reward(b.mdp, _rewards(b), objective=o),
             lambda P, r, b: chain_values.total_reward(P, r)),
        ]
    return cases


def _rewards(built: Built) -> np.ndarray:
    return built.mdp.rewards[0].per_choice(built.mdp)


def _close(a: float, b: float) -> bool:
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= 1e-9 * abs(b) + 1e-12


def _inside(result: MdpResult, want: list[Fraction | float], *, strict: bool) -> list[str]:
    problems = []
    for s, w in enumerate(want):
        lo, hi, v = result.lower[s], result.upper[s], result.values[s]
        if w == math.inf:
            ok = lo == math.inf
        else:
            ok = _close(float(v), float(w))
            if strict:
                ok &= Fraction(lo) <= w <= Fraction(hi)
        if not ok:
            problems.append(f"state {s}: Storm {w} ({float(w)!r}), got {v!r} in [{lo!r}, {hi!r}]")
    if not result.bounds.precise_states().all():
        problems.append("imprecise")
    return problems


@pytest.mark.parametrize("seed", range(30), ids=lambda s: f"seed{s}")
@pytest.mark.parametrize("dyadic", [True, False], ids=["dyadic", "thirds"])
def test_unbounded_values_bounds_and_strategies(seed: int, dyadic: bool) -> None:
    built = _model(seed, dyadic=dyadic)
    mdp = built.mdp
    problems = []
    for formula, check, induced in _unbounded():
        want = storm_values(built, formula)
        result = check(built)
        problems += [f"{formula} {p}" for p in _inside(result, want, strict=dyadic)]
        choices = result.strategy.choices
        assert np.all(mdp.choice_owner[choices] == np.arange(mdp.num_states))
        attained = induced(mdp.transitions[choices].toarray(), _rewards(built)[choices], built)
        problems += [f"{formula} strategy: state {s} attains {a!r}, optimum {float(w)!r}"
                     for s, (a, w) in enumerate(zip(attained, want, strict=True))
                     if not _close(float(a), float(w))]
    assert not problems, "\n".join(problems)


def _stepped() -> list[tuple[str, Check]]:
    cases: list[tuple[str, Check]] = []
    for o in ("min", "max"):
        cases.append((f'P{o}=? [X "goal"]',
                      lambda b, o=o: next_probability(b.mdp, b.mdp.labels["goal"], objective=o)))
        for k in (0, 2, 5):
            cases += [
                (f'P{o}=? ["safe" U<={k} "goal"]',
                 lambda b, o=o, k=k: bounded_reach_probability(
                     b.mdp, b.mdp.labels["goal"], k, objective=o, remain=b.mdp.labels["safe"])),
                (f'P{o}=? [F[{k},{k + 3}] "goal"]',
                 lambda b, o=o, k=k: interval_reach_probability(
                     b.mdp, b.mdp.labels["goal"], k, k + 3, objective=o)),
                (f'R{o}=? [C<={k}]',
                 lambda b, o=o, k=k: cumulative_reward(b.mdp, _rewards(b), k, objective=o)),
            ]
            cases.append((f'R{o}=? [I={k}]',
                          lambda b, o=o, k=k: instantaneous_reward(
                              b.mdp, b.mdp.rewards[0].state, k, objective=o)))
    return cases


@pytest.mark.parametrize("seed", range(15), ids=lambda s: f"seed{s}")
def test_step_bounded_values_and_bounds(seed: int) -> None:
    built = _model(seed, dyadic=True)
    problems = []
    for formula, check in _stepped():
        if "I=" in formula and not built.mdp.rewards[0].state.any():
            continue  # Storm refuses I=k for a structure without state rewards
        want = storm_values(built, formula)
        problems += [f"{formula} {p}" for p in _inside(check(built), want, strict=True)]
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("seed", range(15), ids=lambda s: f"seed{s}")
def test_exact_engine_equals_storms_rationals(seed: int) -> None:
    built = _model(seed, dyadic=False)
    mdp, goal, safe = built.mdp, built.mdp.labels["goal"], built.mdp.labels["safe"]
    entries, rewards = exact_entries(built), exact_rewards(built)
    problems = []
    for o in ("min", "max"):
        runs = {
            f'P{o}=? [F "goal"]': exact_reach_probability(mdp, goal, objective=o,
                                                         probabilities=entries),
            f'P{o}=? ["safe" U "goal"]': exact_reach_probability(
                mdp, goal, objective=o, remain=safe, probabilities=entries),
            f'R{o}=? [F "goal"]': exact_reach_reward(mdp, rewards, goal, objective=o,
                                                    probabilities=entries),
            f'R{o}=? [C]': exact_total_reward(mdp, rewards, objective=o, probabilities=entries),
        }
        for formula, found in runs.items():
            for s, w in enumerate(storm_values(built, formula)):
                got = math.inf if found.infinite[s] else Fraction(
                    int(found.values[s].numerator), int(found.values[s].denominator))
                if got != w:
                    problems.append(f"{formula} state {s}: Storm {w}, got {got}")
    assert not problems, "\n".join(problems)
