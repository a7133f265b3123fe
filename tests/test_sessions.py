"""The pipeline's typed entry points: options that cannot be combined wrongly, sessions
that lump only answers, and internal properties (read by the caller, never reported)."""

from __future__ import annotations

import math
from fractions import Fraction

import pytest

from veribattery.lang import parse_model, parse_properties, parse_property
from veribattery.lang.nodes import Property
from veribattery.pipeline import CheckOptions, Session, check_model, check_model_exact

# Acyclic but for the last state's self-loop: the two s=3 states differ only in x, so a
# quotient that does not keep x apart merges them: 4 blocks for 5 states.
CHAIN = """dtmc
module m
  s : [0..3] init 0;
  x : [0..3] init 0;
  [] s=0 -> 0.4:(s'=1)&(x'=1) + 0.6:(s'=2)&(x'=2);
  [] s=1 | s=2 -> (s'=3);
  [] s=3 -> true;
endmodule
"""
PROPS = parse_properties("P=? [ F s=3 ];\nP=? [ X s=2 ]").properties


def _internal(text: str) -> Property:
    return Property(parse_property(text).formula, name="aside")


def _answers(*, lump: bool = False) -> Session:
    return Session(CheckOptions(keep="answers"), reuse=False, lump=lump)


def test_internal_properties_are_answered_not_reported() -> None:
    run = _answers().check(parse_model(CHAIN), PROPS, internal=(_internal("P=? [ F x=2 ]"),))
    assert [r.property.text for r in run.results] == ["P=? [ F s=3 ]", "P=? [ X s=2 ]"]
    assert math.isclose(float(run.internal_value("aside")), 0.6, rel_tol=1e-15)
    alone = _answers().check(parse_model(CHAIN), PROPS).results
    assert [(r.value, r.lower, r.upper) for r in run.results] == [
        (r.value, r.lower, r.upper) for r in alone]
    with pytest.raises(KeyError):
        run.internal_value("p_success")


def test_a_target_no_state_reaches_is_zero_and_shapes_no_quotient() -> None:
    plain = _answers(lump=True).check(parse_model(CHAIN), PROPS)
    assert plain.quotient is not None and plain.quotient.num_states == 4
    never = _answers(lump=True).check(parse_model(CHAIN), PROPS,
                                      internal=(_internal("P=? [ F x=3 ]"),))
    assert never.internal_value("aside") == 0.0 and never.internal[0].time_s == 0.0
    assert never.quotient is not None and never.quotient.num_states == 4
    # A target some state is in: the quotient keeps x apart (5 states: none worth it).
    live = _answers(lump=True).check(parse_model(CHAIN), PROPS,
                                     internal=(_internal("P=? [ F x=1 ]"),))
    assert live.quotient is None
    assert math.isclose(float(live.internal_value("aside")), 0.4, rel_tol=1e-15)


def test_exact_checks_answer_internal_properties_in_floats() -> None:
    run = check_model_exact(parse_model(CHAIN), PROPS, internal=(_internal("P=? [ F x=2 ]"),))
    assert getattr(run.results[1], "exact", None) == Fraction(3, 5)
    assert math.isclose(float(run.internal_value("aside")), 0.6, rel_tol=1e-15)


def test_what_is_kept() -> None:
    states = check_model(parse_model(CHAIN), PROPS)
    answers = check_model(parse_model(CHAIN), PROPS, options=CheckOptions(keep="answers"))
    assert states.results[0].values.size == 5 and answers.results[0].values.size == 0
    assert [r.value for r in states.results] == [r.value for r in answers.results]


def test_invalid_combinations_cannot_be_built() -> None:
    with pytest.raises(ValueError, match="lumping keeps answers only"):
        Session(lump=True)  # the default keeps every state's values
    with pytest.raises(ValueError, match="keep must be one of"):
        CheckOptions(keep="everything")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="rewards must be one of"):
        Session(rewards="some")  # type: ignore[arg-type]
