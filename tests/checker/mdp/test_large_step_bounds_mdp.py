"""Step bounds too large to iterate on MDPs: ``Pmin``/``Pmax [ F<=10^15 ]`` certified at
once, their step-dependent strategies kept compact, and ``--exact`` refusing them.

GEO: in x=0, [a] moves to the goal x=1 with 1/2 (else stays), [b] with 1/8, to the trap
x=2 with 1/8 (else stays). So Pmax(F<=k x=1) = 1 - 2^-k (always a) and
Pmin(F<=k x=1) = (1 - (3/4)^k) / 2 (always b): 1 and 1/2 in the limit.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from gmpy2 import mpq

from tests.checker.mdp.models import mask, mdp_from
from veribattery.checker import UndecidedResult
from veribattery.checker.certify import horizon
from veribattery.checker.certify.bounds import Bounds, required_precision
from veribattery.checker.mdp import MDP, Objective, StepStrategy, bounded_reach_probability
from veribattery.checker.mdp.exact_steps import exact_rounds
from veribattery.cli import cli
from veribattery.pipeline import check_prism_file

GEO = """mdp
module m
  x : [0..2] init 0;
  [a] x=0 -> 0.5:(x'=0) + 0.5:(x'=1);
  [b] x=0 -> 0.75:(x'=0) + 0.125:(x'=1) + 0.125:(x'=2);
  [] x>0 -> (x'=x);
endmodule
rewards "steps"
  true : 1;
endrewards
"""
HUGE = 10**15


@pytest.mark.parametrize(("prop", "holds"), [
    (f"Pmax>=0.9 [ F<={HUGE} x=1 ]", True),
    (f"Pmin<0.6 [ F<={HUGE} x=1 ]", True),
    (f"Pmin>0.4 [ F<={HUGE} x=1 ]", True),
    (f"Pmax<0.1 [ G<={HUGE} x=0 ]", True),
    (f"Pmin>=0.9 [ F<={2**63 - 1} x=1 ]", False),
])
def test_bounds_far_from_the_value_are_decided_at_once(prop: str, holds: bool) -> None:
    run = check_prism_file(GEO, selectors=(prop,))
    assert run.results[0].value is holds and run.warnings == ()


def test_max_is_one_and_min_a_half_to_within_1e9() -> None:
    run = check_prism_file(GEO, selectors=(f"Pmax=? [ F<={HUGE} x=1 ]",
                                           f"Pmin=? [ F<={HUGE} x=1 ]"))
    most, least = run.results
    assert most.value == 1.0 and most.upper == 1.0  # the unbounded optimum caps it
    assert most.lower is not None and 1 - 1e-14 < most.lower < 1.0
    assert least.lower is not None and least.upper is not None
    assert least.lower < 0.5 < least.upper and least.upper - least.lower < 1e-14
    assert most.precise and least.precise


def test_the_strategy_of_10_to_the_15_steps_is_compact() -> None:
    """Every round after the first few repeats the one before: those are not stored."""
    mdp = mdp_from([
        [[(0, 0.5), (1, 0.5)], [(0, 0.75), (1, 0.125), (2, 0.125)]],
        [[(1, 1)]],
        [[(2, 1)]],
    ])
    goal = mask(3, [1])
    cases: tuple[tuple[Objective, int], ...] = (("max", 0), ("min", 1))
    for objective, choice in cases:
        found = bounded_reach_probability(mdp, goal, HUGE, objective=objective)
        strategy = found.strategy
        assert isinstance(strategy, StepStrategy) and strategy.steps == HUGE
        assert len(strategy.changes) < 2_000
        assert strategy.at(0).choices[0] == choice == strategy.at(HUGE - 1).choices[0]


def test_undecided_bound_stays_undecided_with_the_reason() -> None:
    """Pmin is just below 1/2 at every step bound: only exact arithmetic could say."""
    result = check_prism_file(GEO, selectors=(f"Pmin>=0.5 [ F<={HUGE} x=1 ]",)).results[0]
    assert isinstance(result, UndecidedResult)
    assert result.reason.endswith("<property>:1:16: step bound 1000000000000000 is too large "
                                  "for exact arithmetic (at most 100,000 steps)")


def test_cumulative_reward_that_grows_stops_with_a_lower_bound(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(horizon, "BEYOND_ROUNDS", 2048)
    result = check_prism_file(GEO, selectors=(f"Rmax=? [ C<={HUGE} ]",)).results[0]
    assert result.lower is not None and 2046.99 < result.lower <= 2047.0
    assert result.upper == np.inf and not result.precise


def test_exact_mode_refuses_with_the_bound_and_the_limit(tmp_path: Path) -> None:
    model = tmp_path / "geo.pm"
    model.write_text(GEO)
    runner = CliRunner()
    result = runner.invoke(cli, ["prism", str(model), "--exact", "--json", "--property",
                                 "Pmax=? [ F<=2 x=1 ]", "--property", "Pmin=? [ F<=2 x=1 ]"])
    assert result.exit_code == 0
    assert '"exact": "3/4"' in result.stdout and '"exact": "7/32"' in result.stdout
    for prop, column in ((f"Pmax=? [ F<={HUGE} x=1 ]", 13),
                         (f"Rmin=? [ I={HUGE} ]", 12), (f"Pmin=? [ F>={HUGE} x=1 ]", 13)):
        result = runner.invoke(cli, ["prism", str(model), "--exact", "--property", prop])
        assert result.exit_code == 2
        assert result.stderr.strip() == (
            f"error: <property>:1:{column}: step bound {HUGE} is too large for exact "
            "arithmetic (at most 100,000 steps)")


# ---------------------------------------------------------------------------
# The kernel against exact Bellman rounds, with the limits made small
# ---------------------------------------------------------------------------


def _random_mdp(seed: int, dyadic: bool, n: int = 8) -> tuple[MDP, np.ndarray]:
    """Two choices per state, a trap (the last state) and two goals; rows of 1/2, 1/4,
    ... (exactly stochastic) or normalised in floating point."""
    rng = np.random.default_rng(seed)
    states: list[list[list[tuple[int, float]]]] = []
    for state in range(n - 1):
        choices = []
        for _ in range(2):
            successors = (state, *rng.choice(n, 2, replace=False))
            if dyadic:
                weights = np.array([0.5, 0.25, 0.25])
            else:
                weights = rng.random(3) + 0.1
                weights /= weights.sum()
            choices.append([(int(t), float(w)) for t, w in zip(successors, weights,
                                                                strict=True)])
        states.append(choices)
    states.append([[(n - 1, 1.0)]])
    goal = mask(n, list(rng.choice(n - 1, 2, replace=False)))
    return mdp_from(states), goal


def _exact(mdp: MDP, goal: np.ndarray, objective: Objective, k: int) -> list[Fraction]:
    probabilities = np.frompyfunc(mpq, 1, 1)(mdp.transitions.data)
    start = np.where(goal, mpq(1), mpq(0)).astype(object)
    found = exact_rounds(mdp, probabilities, start, ~goal, start, objective, k)
    return [Fraction(int(v.numerator), int(v.denominator)) for v in found]


def _contains(found: Bounds, exact: list[Fraction]) -> bool:
    return all(Fraction(float(lo)) <= e and (hi == np.inf or e <= Fraction(float(hi)))
               for lo, e, hi in zip(found.lower, exact, found.upper, strict=True))


@pytest.mark.parametrize("objective", ["min", "max"])
@pytest.mark.parametrize("dyadic", [True, False])
@pytest.mark.parametrize("precision", [(1e-9, 1e-12), (1e-300, 1e-300)])
@pytest.mark.parametrize("seed", range(4))
def test_bounds_beyond_the_rounds_run_contain_the_exact_values(
        objective: Objective, dyadic: bool, precision: tuple[float, float], seed: int,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``U<=300`` from at most 64 rounds (bounds above 40 steps): the enclosure of the
    rounds not run holds the exact 300-round optimum of the stored MDP."""
    monkeypatch.setattr(horizon, "ROUND_LIMIT", 40)
    monkeypatch.setattr(horizon, "BEYOND_ROUNDS", 64)
    monkeypatch.setattr(horizon, "FIRST_CHECK", 16)
    mdp, goal = _random_mdp(seed, dyadic)
    with required_precision(*precision):
        found = bounded_reach_probability(mdp, goal, 300, objective=objective)
    assert _contains(found.bounds, _exact(mdp, goal, objective, 300))


#: Rows stored a little above 1 (0.9 + 0.1 is 1 + 2^-55 in doubles), so the bounds of
#: F<=k may pass 1 a little: those of G<=k, its complement, must stay in [0, 1].
ABOVE_ONE = """{kind}
module m
  x : [0..1] init 0;
  [a] x=0 -> 0.9:(x'=0) + 0.1:(x'=1);
  [b] x=0 -> 0.5:(x'=0) + 0.5:(x'=1);
  [] x=1 -> (x'=1);
endmodule
"""


@pytest.mark.parametrize(("kind", "prop"), [
    ("mdp", "Pmin=? [ G<=1000000000000000 x=0 ]"),
    ("mdp", "Pmax=? [ G<=1000000000000000 x=0 ]"),
    ("dtmc", "P=? [ G<=1000000000000000 x=0 ]"),
])
def test_complements_stay_probabilities(kind: str, prop: str) -> None:
    model = ABOVE_ONE.format(kind=kind)
    if kind == "dtmc":
        model = model.replace("  [b] x=0 -> 0.5:(x'=0) + 0.5:(x'=1);\n", "")
    (result,) = check_prism_file(model, selectors=(prop,)).results
    assert 0.0 == result.lower <= result.value <= result.upper < 1e-13


#: The DTMC test's SWAP with a second choice in s=0 earning half as much.
SWAP_MDP = """mdp
module m
  s : [0..1] init 0;
  [a] s=0 -> 0.25:(s'=1) + 0.75:(s'=0);
  [b] s=0 -> 0.25:(s'=1) + 0.75:(s'=0);
  [c] s=1 -> 0.25:(s'=0) + 0.75:(s'=1);
endmodule
rewards "r"
  [a] true : 1;
  [b] true : 0.5;
endrewards
"""


@pytest.mark.parametrize(("bound", "factor"), [("max", 1), ("min", Fraction(1, 2))])
def test_cumulative_reward_is_carried_by_its_gain(bound: str, factor: Fraction,
                                                 gains_carried: list[int]) -> None:
    """``C<=10^6`` (k/2 + 1 - 2^-k from s=0, halved for the minimum): once the steps'
    increments agree in every state the rounds left are carried forward; 10^6 rounds
    took half a minute on QVBS's resource-gathering (94 states; Storm: 0.6 s)."""
    k = 10**6
    result = check_prism_file(SWAP_MDP, selectors=(f"R{bound}=? [ C<={k} ]",)).results[0]
    exact = factor * (Fraction(k, 2) + 1 - Fraction(1, 2**k))
    assert result.precise and result.lower is not None and result.upper is not None
    assert Fraction(result.lower) <= exact <= Fraction(result.upper)
    assert gains_carried and gains_carried[-1] > k // 3
