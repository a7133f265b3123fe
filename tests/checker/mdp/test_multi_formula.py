"""``multi(...)`` properties through the MDP checker: hand-solved values, PRISM's rules
(DTMC, Pareto, infeasible, strict bounds), the error estimate of numerical answers and
the exact witness of achievability on the boundary."""

from __future__ import annotations

import json
import math
from fractions import Fraction
from pathlib import Path

import pytest

from veribattery.checker import CheckResult, UndecidedResult
from veribattery.errors import CheckError, PrismSemanticError
from veribattery.lang import parse_model, parse_properties
from veribattery.pipeline.mdp import check_mdp_model

# From s=0 a strategy mixes a (to s=2), b (to s=3, cost 1) and c (to s=2 or s=3,
# 1/2 each, cost 2). With p_a + p_b + p_c = 1:
#   P(F s=2) = p_a + p_c/2,  P(F s=3) = p_b + p_c/2,  cost = p_b + 2 p_c.
FORK = """mdp
module m
  s : [0..3] init 0;
  [a] s=0 -> (s'=2);
  [b] s=0 -> (s'=3);
  [c] s=0 -> 0.5:(s'=2) + 0.5:(s'=3);
  [] s>=2 -> true;
endmodule
rewards "cost"
  [b] true : 1;
  [c] true : 2;
endrewards
"""

# s=0: a pays 1 now and 1 next step (via s=1); b pays 0 now and 5 next step (via s=2).
#   C<=1 = p_a,  C<=2 = 2 p_a + 5 p_b,  C = 2 p_a + 5 p_b as well (s=3 is free).
STEPS = """mdp
module m
  s : [0..3] init 0;
  [a] s=0 -> (s'=1);
  [b] s=0 -> (s'=2);
  [] s=1 -> (s'=3);
  [] s=2 -> (s'=3);
  [] s=3 -> true;
endmodule
rewards "r"
  [a] true : 1;
  s=1 : 1;
  s=2 : 5;
endrewards
"""


def check(model: str, formula: str) -> CheckResult:
    props = parse_properties(formula + "\n", name="t.props")
    run = check_mdp_model(parse_model(model, name="t.prism"), props.properties,
                          props_file=props)
    return run.results[0]


@pytest.mark.parametrize(("formula", "expected"), [
    ('multi(Pmax=? [ F s=3 ], R{"cost"}<=0.4 [ C ])', 0.4),  # p_b = 0.4
    ('multi(R{"cost"}min=? [ C ], P>=0.7 [ F s=3 ])', 0.7),  # p_b = 0.7
    ("multi(Pmin=? [ F s=2 ], P<=0.25 [ F s=3 ])", 0.75),  # P(F s=2) = 1 - P(F s=3)
    ("multi(Pmin=? [ F s=2 ], P<0.25 [ F s=3 ])", 0.75),  # strict read as non-strict
    # 1 - p_b - p_c/2 with p_b + 2 p_c >= 1/2: c is cheaper in probability (p_c = 1/4)
    ('multi(Pmax=? [ G s!=3 ], R{"cost"}>=0.5 [ C ])', 0.875),
    ('multi(R{"cost"}max=? [ C ], P>=0.5 [ G s!=3 ])', 2.0),  # p_c = 1: P(F s=3) = 1/2
    ("multi(Pmax=? [ s=0 ], P>=0.5 [ F s=2 ])", 1.0),  # a state formula: now
    ("multi(Pmax=? [ s=2 ], P>=0.5 [ F s=2 ])", 0.0),
    ("multi(Pmax=? [ true U s=3 ], P>=0.5 [ F s=2 ])", 0.5),
])
def test_numerical_queries_solved_by_hand(formula: str, expected: float) -> None:
    result = check(FORK, formula)
    assert result.value == pytest.approx(expected, abs=1e-6)


def test_numerical_answers_are_not_certified_and_carry_an_error_estimate() -> None:
    result = check(FORK, 'multi(Pmax=? [ F s=3 ], R{"cost"}<=0.4 [ C ])')
    assert not result.certified and not result.precise
    assert result.lower == pytest.approx(0.4 - 1e-6) and result.upper == pytest.approx(0.4 + 1e-6)


@pytest.mark.parametrize(("formula", "expected"), [
    # the boundary: p_a = p_b = 1/2 costs exactly 1/2; an exact witness decides it
    ('multi(P>=0.5 [ F s=2 ], P>=0.5 [ F s=3 ], R{"cost"}<=0.5 [ C ])', True),
    ('multi(P>=0.5 [ F s=2 ], P>=0.5 [ F s=3 ], R{"cost"}<=0.4 [ C ])', False),
    ('multi(P>=0.2 [ F s=2 ], P>=0.2 [ F s=3 ], R{"cost"}<=0.5 [ C ])', True),
])
def test_achievability(formula: str, expected: bool) -> None:
    result = check(FORK, formula)
    assert result.value is expected
    assert result.certified is expected  # "true" has an exact witness, "false" none


def test_achievability_too_close_to_call_is_undecided() -> None:
    # the exact optimum is 1/2; 0.5 + 1e-9 is missed, by less than HiGHS can tell:
    # reported as undecided (never a guessed boolean, never an input error)
    result = check(FORK, 'multi(P>=0.5 [ F s=2 ], P>=0.5 [ F s=3 ], R{"cost"}<=0.499999999 [ C ])')
    assert isinstance(result, UndecidedResult)
    assert "cannot be decided" in result.reason


@pytest.mark.parametrize(("formula", "expected"), [
    # C<=2 >= 3 needs 2 p_a + 5 p_b >= 3, so p_b >= 1/3 and C<=1 = p_a <= 2/3
    ('multi(R{"r"}max=? [ C<=1 ], R{"r"}>=3 [ C<=2 ])', Fraction(2, 3)),
    ('multi(R{"r"}max=? [ C<=2 ], R{"r"}>=0.5 [ C<=1 ])', Fraction(7, 2)),  # p_a = 1/2
    ('multi(R{"r"}min=? [ C ], R{"r"}>=0.5 [ C<=1 ])', Fraction(2, 1)),  # p_a = 1
    ('multi(R{"r"}max=? [ C<=0 ], R{"r"}>=0.5 [ C<=1 ])', Fraction(0)),
])
def test_step_bounded_rewards_need_the_step_count(formula: str, expected: Fraction) -> None:
    assert check(STEPS, formula).value == pytest.approx(float(expected), abs=1e-6)


def test_a_step_bound_too_large_to_unfold_is_refused() -> None:
    """``C<=10^15`` would unfold STEPS (5 transitions) into 10^15 + 1 copies: refused,
    naming the bound, instead of building them."""
    formula = 'multi(R{"r"}max=? [ C<=1 ], R{"r"}>=3 [ C<=1000000000000000 ])'
    with pytest.raises(CheckError) as raised:
        check(STEPS, formula)
    assert str(raised.value) == ("t.props:1:44: a step bound of 1000000000000000 unfolds the "
                                 "model into 5,000,000,000,000,005 transitions (at most "
                                 "20,000,000): use a smaller bound")


def test_infeasible_numerical_query_is_nan_with_an_error_naming_the_property() -> None:
    # PRISM's own regression suite expects NaN here (multi-general/test2.nm.props#2); the
    # issue counts it as bad input: the run carries an error at the property's position
    text = "multi(Pmax=? [ F s=3 ], P>=0.95 [ F s=2 ], P>=0.1 [ F s=3 ])"
    run = check_mdp_model(parse_model(FORK), parse_properties(text, name="t.props").properties)
    assert math.isnan(run.results[0].value)
    assert run.warnings == ()
    assert run.errors == (f"t.props:1:1: {text}: undefined (NaN): multi(...) has no strategy "
                          "that meets its bounded objectives, so the =? objective has no "
                          "optimum (NaN, as PRISM reports it)",)  # (finite rewards: none asked)


def test_an_infeasible_query_with_rewards_says_finite_total_rewards() -> None:
    text = 'multi(Pmax=? [ F s=3 ], R{"cost"}<=0.5 [ C ], P>=0.9 [ F s=3 ])'
    run = check_mdp_model(parse_model(FORK), parse_properties(text, name="t.props").properties)
    assert math.isnan(run.results[0].value)
    assert "no strategy that meets its bounded objectives with finite total rewards" in (
        run.errors[0])


@pytest.mark.parametrize(("model", "formula", "message"), [
    (FORK.replace("mdp", "dtmc", 1).replace("[b] s=0", "[b] s=9").replace("[c] s=0", "[c] s=9"),
     "multi(P>=0.5 [ F s=2 ])", "multi\\(...\\) is for MDPs"),
    (FORK, "multi(Pmax=? [ F s=2 ], Pmin=? [ F s=3 ])", "Pareto queries"),
    (FORK, "P>=0.5 [ F s=2 ] & multi(P>=0.5 [ F s=2 ])", "must be the whole property"),
    (FORK, "multi(P>=0.5 [ F s=2 ], s=0)", "must be P or R operators"),
])
def test_prism_rules(model: str, formula: str, message: str) -> None:
    with pytest.raises(PrismSemanticError, match=message):
        check(model, formula)


@pytest.mark.parametrize(("formula", "message"), [
    ("multi(P=? [ F s=2 ], P>=0.5 [ F s=3 ])", "needs a direction"),
    ("multi(Pmax=? [ F<=2 s=2 ], P>=0.5 [ F s=3 ])", "P objectives over F phi"),
    ('multi(Rmax=? [ F s=2 ], P>=0.5 [ F s=3 ])', "R objectives over C"),
])
def test_unsupported_objectives(formula: str, message: str) -> None:
    with pytest.raises(CheckError, match=message):
        check(FORK, formula)


MODELS = {"fork": FORK, "steps": STEPS}


@pytest.mark.parametrize(("name", "formula"), [
    ("fork", 'multi(Pmax=? [ F s=3 ], R{"cost"}<=0.4 [ C ])'),
    ("fork", 'multi(Pmax=? [ G s!=3 ], R{"cost"}>=0.5 [ C ])'),
    ("fork", 'multi(R{"cost"}max=? [ C ], P>=0.5 [ G s!=3 ])'),
    ("steps", 'multi(R{"r"}max=? [ C<=1 ], R{"r"}>=3 [ C<=2 ])'),
    ("steps", 'multi(R{"r"}max=? [ C<=2 ], R{"r"}>=0.5 [ C<=1 ])'),
])
def test_numerical_queries_agree_with_storm(name: str, formula: str, tmp_path: Path) -> None:
    # Storm approximates the Pareto set from inside (precision 1e-4 by default), and
    # on the boundary of an achievability query it can answer false where an exact
    # witness says true: only numerical queries are compared, to Storm's precision.
    stormpy = pytest.importorskip("stormpy")
    path = tmp_path / "model.prism"
    path.write_text(MODELS[name], encoding="utf-8")
    program = stormpy.parse_prism_program(str(path))
    props = stormpy.parse_properties(formula, program)
    built = stormpy.build_model(program, props)
    theirs = stormpy.model_checking(built, props[0]).get_value(built.initial_states[0])
    assert check(MODELS[name], formula).value == pytest.approx(float(theirs), abs=1e-3)


def test_prism_json_says_what_is_not_certified(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from veribattery.cli import cli

    model, props = tmp_path / "fork.prism", tmp_path / "fork.props"
    model.write_text(FORK, encoding="utf-8")
    props.write_text('multi(Pmax=? [ F s=3 ], R{"cost"}<=0.4 [ C ]);\n'
                     'multi(P>=0.2 [ F s=2 ], P>=0.2 [ F s=3 ]);\n'
                     "(1.0 / 0.0) / (1.0 / 0.0);\n", encoding="utf-8")
    result = CliRunner().invoke(cli, ["prism", str(model), "--props", str(props), "--json"])
    assert result.exit_code == 0, result.output
    numerical, achievable, undefined = json.loads(result.stdout)["results"]
    assert numerical["certified"] is False and numerical["precise"] is False
    assert numerical["bounds"] == pytest.approx([0.4 - 1e-6, 0.4 + 1e-6])
    assert achievable == {"property": achievable["property"], "value": True}  # witnessed
    assert undefined["value"] == "NaN"  # as PRISM prints it; null would read "no result"
    assert "not certified" in result.stderr


@pytest.mark.parametrize(("formula", "expected"), [
    ('multi(R{"cost"}min=? [ C ], P>=0.7 [ F s=3 ])', Fraction(7, 10)),  # p_b = 0.7
    ('multi(R{"cost"}min=? [ C ], P>=0.7 [ F s=2 ])', Fraction(0)),  # p_a = 1 is free
    ('multi(R{"cost"}min=? [ C<=1 ], P>=0.25 [ F s=3 ])', Fraction(1, 4)),  # stepped
    # STEPS: 2 p_a + 5 p_b with p_b >= 1/2
    ('multi(R{"r"}min=? [ C ], P>=0.5 [ F s=2 ])', Fraction(7, 2)),
])
def test_least_reward_under_a_probability_bound_is_certified(formula: str,
                                                             expected: Fraction) -> None:
    """The two-objective shape comes from the weighted-sum front: a certified interval
    that holds the hand-solved value (every other shape stays a linear programme)."""
    result = check(STEPS if '"r"' in formula else FORK, formula)
    assert result.certified and result.precise
    assert result.lower is not None and result.upper is not None
    assert Fraction(result.lower) <= expected <= Fraction(result.upper)
    assert result.value == pytest.approx(float(expected), abs=1e-12)


def test_prism_json_of_a_certified_multi_answer(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from veribattery.cli import cli

    model, props = tmp_path / "fork.prism", tmp_path / "fork.props"
    model.write_text(FORK, encoding="utf-8")
    props.write_text('multi(R{"cost"}min=? [ C ], P>=0.7 [ F s=3 ]);\n', encoding="utf-8")
    result = CliRunner().invoke(cli, ["prism", str(model), "--props", str(props), "--json"])
    assert result.exit_code == 0, result.output
    (answer,) = json.loads(result.stdout)["results"]
    assert "certified" not in answer  # the key is there only for uncertified results
    low, high = answer["bounds"]
    assert low <= 0.7 <= high and high - low < 1e-12
    assert "not certified" not in result.stderr
