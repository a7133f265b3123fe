"""PRISM's whole DTMC property language, on a small chain solved by hand.

The chain (``MODEL``): from s=0 go to the absorbing s=1 w.p. 1/3 or to s=2 w.p.
2/3; {2,3,4} is a periodic BSCC (2->3, 3->2 w.p. 1/4, 3->4 w.p. 3/4, 4->3) with
stationary distribution pi(2,3,4) = (1/8, 1/2, 3/8). Reward "r": 2 in s=3 (state
reward), 1 on the step leaving s=0 (transition reward).
"""

from __future__ import annotations

import math
from fractions import Fraction as Q

import pytest

from veribattery.errors import VeribatteryError
from veribattery.pipeline import check_prism_file

MODEL = """dtmc
module m
  s : [0..4] init 0;
  [] s=0 -> 1/3:(s'=1) + 2/3:(s'=2);
  [] s=1 -> (s'=1);
  [] s=2 -> (s'=3);
  [] s=3 -> 1/4:(s'=2) + 3/4:(s'=4);
  [] s=4 -> (s'=3);
endmodule
rewards "r"
  s=3 : 2;
  [] s=0 : 1;
endrewards
"""

INF = math.inf

CASES = [
    # steady state: sum over BSCCs of reach probability times stationary mass
    ("S=? [ s=3 ]", Q(2, 3) * Q(1, 2)),
    ("S=? [ s=1 ]", Q(1, 3)),
    ("S=? [ s=2 ]", Q(2, 3) * Q(1, 8)),
    ("S>0.3 [ s=3 ]", True),
    ("S<0.3 [ s=3 ]", False),
    ('R{"r"}=? [ S ]', Q(2, 3) * (Q(1, 2) * 2)),
    ('R{"r"}=? [ C ]', INF),
    ('filter(state, R{"r"}=? [ C ], s=1)', 0),
    ('R{"r"}=? [ C<=1 ]', 1),
    # filters
    ("filter(max, S=? [ s=3 ], s>1)", Q(1, 2)),
    ("filter(min, S=? [ s=3 ], s>0)", 0),
    ("filter(count, s>1)", 3),
    ("filter(sum, s)", 10),
    ("filter(+, s)", 10),
    ("filter(avg, s)", 2),
    ("filter(first, s, s>2)", 3),
    ("filter(state, s, s>3)", 4),
    ("filter(forall, s<5)", True),
    ("filter(&, s<4)", False),
    ("filter(exists, s=4)", True),
    ('filter(forall, "init" <=> s=0)', True),
    ('filter(max, P=? [ F s=1 ], "init")', Q(1, 3)),
    ("P=? [ F s=1 {s=0} ]", Q(1, 3)),
    ("P=? [ F s=1 {s>=0}{max} ]", Q(1, 1)),
    ("P=? [ F s=1 {s>=2}{min} ]", 0),
    ("filter(argmax, s)", False),
    ("filter(print, P=? [ F s=1 ])", Q(1, 3)),
    # CTL
    ("E [ F s=1 ]", True),
    ("A [ F s=1 ]", False),
    ("E [ G s!=1 ]", True),
    ("A [ G s<5 ]", True),
    ("E [ X s=2 ]", True),
    ("A [ X s>0 ]", True),
    ("A [ X s=2 ]", False),
    ("A [ s=0 U s>0 ]", True),
    ("A [ s<3 W s=3 ]", True),
    ("A [ s=0 W s=2 ]", False),
    ("E [ s=0 W s=2 ]", True),
    ("E [ s=2 R s<2 ]", True),
    ("A [ s=2 R s<2 ]", False),
    ("E [ s=0 ]", True),
    ("filter(forall, E [ G s>1 ] <=> s>1)", True),
    # every step bound
    ("P=? [ F=2 s=3 ]", Q(2, 3)),
    ("P=? [ F[3,3] s=2 ]", Q(2, 3) * Q(1, 4)),
    ("P=? [ F>=3 s=4 ]", Q(2, 3)),
    ("P=? [ F>2 s=1 ]", Q(1, 3)),
    ("P=? [ F<1 s=0 ]", 1),
    ("P=? [ G<=1 s<2 ]", Q(1, 3)),
    ("P=? [ G>=2 s!=1 ]", Q(2, 3)),
    ("P=? [ G[1,2] s>=2 ]", Q(2, 3)),
    ("P=? [ s=0 U[1,1] s=2 ]", Q(2, 3)),
    ("P=? [ s=0 U>=2 s=2 ]", 0),
    ("P=? [ s=0 W s=9 ]", 0),
    ("P=? [ s<2 W s=9 ]", Q(1, 3)),
    ("P=? [ s=1 R s!=2 ]", Q(1, 3)),
    ("P=? [ s=0 R<=1 s<=1 ]", 1),
    ("P=? [ s=1 R<=1 s<=1 ]", Q(1, 3)),
    ("P=? [ s=0 ]", 1),
    ("Pmax=? [ F s=1 ]", Q(1, 3)),
    # rewards until, steps
    ('R{"r"}=? [ s!=1 U s=2 ]', INF),
    ('filter(state, R{"r"}=? [ s>=2 U s=4 ], s=2)', Q(8, 3)),
    ('R{"r"}=? [ s=0 ]', 0),
    ('R{"r"}=? [ s=1 ]', INF),
    ('R{"r"}=? [ X s>0 ]', 1),
    ('R{"r"}=? [ X s=2 ]', INF),
    ('filter(state, R{"r"}=? [ X s=3 ], s=4)', 0),
    ('filter(state, R{"r"}=? [ X s>=2 ], s=3)', 2),
    ("T=? [ F s!=0 ]", 1),
    ("T=? [ F s>=2 ]", INF),
    # properties as expressions
    ("P=? [ F s=1 ] + P=? [ F s=2 ]", 1),
    ("1 - S=? [ s=3 ]", Q(2, 3)),
    ("round(P=? [ F s=2 ])", 1),
    ("floor(3 * P=? [ F s=2 ])", 2),
    ("pow(2, 3)", 8),
    ("pow(2, -1.0)", Q(1, 2)),
    ("2 ^ 3", 8),
    ("s + 1", 1),
    ("s = 0", True),
    ("P>0.5 [ F s=2 ] & S<1 [ s=1 ]", True),
    ("max(P=? [ F s=1 ], 0.5)", Q(1, 2)),
    ("P=? [ F s=1 ] > 0.3 ? 7 : 8", 7),
]


@pytest.mark.parametrize(("text", "expected"), CASES, ids=[c[0] for c in CASES])
def test_value(text: str, expected: object) -> None:
    run = check_prism_file(MODEL, selectors=(text,))
    value = run.results[0].value
    if isinstance(expected, bool):
        assert value is expected
    elif expected == INF:
        assert value == INF
    else:
        assert value == pytest.approx(float(expected), rel=1e-9, abs=1e-12)


def test_named_property_references_and_late_constants() -> None:
    props = '"a": P=? [ F s=1 ];\n2 * "a";\nk * "a"; const int k = 3;\n'
    run = check_prism_file(MODEL, props_source=props)
    assert [r.value for r in run.results] == pytest.approx([1 / 3, 2 / 3, 1.0])


def test_several_initial_states_give_a_range() -> None:
    model = MODEL.replace("s : [0..4] init 0;", "s : [0..4];") + "init s=2 | s=3 endinit\n"
    run = check_prism_file(model, selectors=("P=? [ F=1 s=3 ]", "S=? [ s=3 ]", "s>1"))
    first, second, third = run.results
    assert (first.value, first.value_range) == (0.0, (0.0, 1.0))
    assert (second.value, second.value_range) == (pytest.approx(0.5), None)
    assert third.value is True


def test_print_filters_list_states_in_prism_order() -> None:
    run = check_prism_file(MODEL, selectors=("filter(printall, s*2, s>2)", "filter(argmin, s)"))
    assert run.results[0].printed == ("3:(s=3)=6", "4:(s=4)=8")
    assert run.results[1].printed == ("0:(s=0)",)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("filter(min, s, s>9)", "empty"),
        ("filter(state, s, s>2)", "exactly one state"),
        ("filter(frobnicate, s)", "unknown filter operator"),
        ("P=? [ F<0 s=1 ]", "no step"),
        ("P=? [ G[2,1] s=1 ]", "no step"),
        ("E [ F<=2 s=1 ]", "CTL"),
        ("P=? [ F<=2 G s=1 ]", "step bound on F .eventually. over a path formula"),
        ("pow(2, -1)", "negative exponent"),
        ("filter(max, s=1)", "numeric"),
        ("S=? [ s ]", "bool"),
    ],
)
def test_prism_errors(text: str, message: str) -> None:
    with pytest.raises(VeribatteryError, match=message):
        check_prism_file(MODEL, selectors=(text,))


def test_negative_rewards_are_rejected() -> None:
    model = MODEL.replace("s=3 : 2;", "s=3 : -2;")
    with pytest.raises(VeribatteryError, match="negative rewards"):
        check_prism_file(model, selectors=('R{"r"}=? [ F s=1 ]',))


def test_unsupported_property_is_skipped_when_the_whole_file_is_checked() -> None:
    run = check_prism_file(MODEL, props_source="P=? [ F<=2 G s=1 ];\nS=? [ s=1 ];\n")
    assert [r.value for r in run.results] == pytest.approx([1 / 3])
    assert any("LTL takes unbounded operators only" in w for w in run.warnings)


def test_stationary_distribution_of_a_strongly_drifting_chain() -> None:
    """Birth-death chain on 0..60 (up 0.9, down 0.1, reflecting): pi_k ~ 9^k, so the
    initial state's mass is 9^-60 and a solve anchored there would be useless."""
    model = """dtmc
module m
  s : [0..60] init 0;
  [] true -> 0.9:(s'=min(s+1,60)) + 0.1:(s'=max(s-1,0));
endmodule
"""
    run = check_prism_file(model, selectors=("S=? [ s=60 ]", "S=? [ s=59 ]"))
    top = Q(8, 9) / (1 - Q(1, 9) ** 61)
    assert run.results[0].value == pytest.approx(float(top), rel=1e-9)
    assert run.results[1].value == pytest.approx(float(top / 9), rel=1e-9)


#: A chain whose reward "r" is earned only on the way from s=0 to s=1: from s=2 on,
#: no reward can be reached, so every expectation there is exactly 0 (a solver alone
#: left ``0 +- 2e-270``, where PRISM and Storm print 0).
REWARD_FREE = """dtmc
module m
  s : [0..4] init 0;
  [a] s=0 -> 1/2:(s'=1) + 1/2:(s'=2);
  [] s=1 -> (s'=4);
  [] s=2 -> 1/3:(s'=3) + 2/3:(s'=4);
  [] s=3 -> 1/2:(s'=2) + 1/2:(s'=4);
  [] s=4 -> true;
endmodule
rewards "r"
  [a] true : 3;
  s=1 : 2;
endrewards
"""


@pytest.mark.parametrize(("path", "states"), [
    ("F s=4", (2, 3, 4)), ("C", (2, 3, 4)), ("C<=5", (2, 3, 4)), ("I=2", (2, 3, 4)),
    ("S", (2, 3, 4)), ("F s=4 || F s=3", (2, 3)),  # (from s=4 the condition is impossible)
])
def test_states_that_reach_no_reward_get_exactly_zero(path: str, states: tuple[int, ...]
                                                       ) -> None:
    run = check_prism_file(REWARD_FREE, selectors=tuple(
        f'filter(state, R{{"r"}}=? [ {path} ], s={state})' for state in states))
    for result in run.results:
        assert (result.lower, result.value, result.upper) == (0, 0, 0)


def test_states_that_reach_a_reward_keep_their_value() -> None:
    run = check_prism_file(REWARD_FREE, selectors=('R{"r"}=? [ F s=4 ]', 'R{"r"}=? [ F s=3 ]'))
    assert run.results[0].value == pytest.approx(3 + 0.5 * 2, rel=1e-12)
    assert run.results[1].value == INF  # (s=3 is not reached almost surely: infinite)
