"""LTL path formulas on small DTMCs and MDPs, values worked out by hand.

Float and exact answers must both be the hand values; the co-safe reward cases follow
PRISM's reading of a reward's path (its ``dtmc_rewards`` cosafety tests: every
proposition, ``true`` included, is settled by reading its position's state).
"""

from __future__ import annotations

import math
from fractions import Fraction

import pytest

from veribattery import check_prism_file
from veribattery.checker.mdp.witness import strategy_refusal
from veribattery.errors import CheckError
from veribattery.lang.parser import parse_property

#: s0 splits to s1 and s2; {s1, s3} is a bottom component visiting "a" (s1) infinitely
#: often, never staying in it; s2 ("b") is absorbing.
CHAIN = """dtmc
module m
  s : [0..3] init 0;
  [] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);
  [] s=1 -> 0.5:(s'=1) + 0.5:(s'=3);
  [] s=2 -> (s'=2);
  [] s=3 -> 0.25:(s'=1) + 0.75:(s'=3);
endmodule
label "a" = s=1;
label "b" = s=2;
rewards "steps"
  true : 1;
endrewards
"""

#: s0: "go" splits to s1/s2, "stay" goes to s3; s3 chooses between s1 ("a") and itself.
MDP = """mdp
module m
  s : [0..3] init 0;
  [go] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);
  [stay] s=0 -> (s'=3);
  [] s=1 -> 0.5:(s'=1) + 0.5:(s'=3);
  [] s=2 -> (s'=2);
  [a] s=3 -> (s'=1);
  [b] s=3 -> (s'=3);
endmodule
label "a" = s=1;
label "b" = s=2;
rewards "steps"
  true : 1;
endrewards
"""

#: A line s0 -> s1 -> s2 -> s3 (absorbing) with state and action rewards: one step from
#: s_i earns 5, 12, 11 (from s3: 0; the structure "b" earns 30 there).
LINE = """dtmc
module m
  s : [0..3] init 0;
  [] s<3 -> (s'=s+1);
  [] s=3 -> true;
endmodule
rewards "a"
  s=0 : 2; [] s=0 : 3;
  s=1 : 5; [] s=1 : 7;
  s=2 : 11;
endrewards
rewards "b"
  s=0 : 2; [] s=0 : 3;
  s=1 : 5; [] s=1 : 7;
  s=2 : 11;
  s=3 : 17; [] s=3 : 13;
endrewards
"""


def _values(model: str, props: list[str], *, exact: bool) -> list[object]:
    run = check_prism_file(model, props_source="\n".join(props), exact=exact)
    return [r.exact if exact and r.exact is not None else r.value for r in run.results]


CHAIN_CASES = [
    ('P=? [ G F "a" ]', Fraction(1, 2)),  # the {s1, s3} half
    ('P=? [ F G "a" ]', Fraction(0)),  # s1 is left almost surely
    ('P=? [ F G !"b" ]', Fraction(1, 2)),
    ('P=? [ (G !"b") & (G F "a") ]', Fraction(1, 2)),
    ('P=? [ F ("a" & (X s=3)) ]', Fraction(1, 2)),  # s1 -> s3 happens, once there
    ('P=? [ X X "a" ]', Fraction(1, 4)),  # s0 -> s1 -> s1
    ('P=? [ (X "a") U "b" ]', Fraction(0)),  # "b" is not entered from "a"
    ('P=? [ !"a" U (X "b") ]', Fraction(1, 2)),  # s0 itself: X "b" holds there already
    ('P=? [ (X s=2) | (X X s=3) ]', Fraction(1, 2) + Fraction(1, 4)),
    ('P=? [ G ("a" => (X (s=1 | s=3))) ]', Fraction(1)),
    ('P=? [ "a" R !"b" ]', Fraction(1, 2)),  # G !"b" on the {s1, s3} half
]


@pytest.mark.parametrize("exact", [False, True])
def test_probabilities_on_a_chain(exact: bool) -> None:
    props = [text for text, _ in CHAIN_CASES]
    found = _values(CHAIN, props, exact=exact)
    for (text, want), got in zip(CHAIN_CASES, found, strict=True):
        assert (got == want) if exact else math.isclose(got, float(want), abs_tol=1e-12), text


def test_path_quantifiers_over_ltl_on_a_chain() -> None:
    props = ['E [ G F "a" ]', 'A [ G F "a" ]', 'E [ F G "a" ]',
             'A [ (F G !"a") | (F "b") ]', 'filter(forall, E [ G F "a" ], s=1 | s=3)',
             'filter(forall, A [ G F "a" ], s=1 | s=3)', 'filter(count, E [ F G "b" ])']
    # Paths, not probabilities: s1 forever satisfies F G "a" and refutes the fourth; s3
    # forever refutes A [ G F "a" ] from s1 and s3; F G "b" is possible from s0 and s2.
    assert _values(CHAIN, props, exact=False) == [True, False, True, False, True, False, 2]


MDP_CASES = [
    ('Pmax=? [ G F "a" ]', Fraction(1)),  # stay, then "a" from s3 each time
    ('Pmin=? [ G F "a" ]', Fraction(0)),  # stay, then s3 forever
    ('Pmax=? [ F G s=3 ]', Fraction(1)),
    ('Pmin=? [ F G s=3 ]', Fraction(0)),
    ('Pmin=? [ F G !"b" ]', Fraction(1, 2)),  # go: half into s2
    ('Pmax=? [ (X "a") | (X X "a") ]', Fraction(1)),  # stay, then s3 -> s1
    ('Pmin=? [ (X "a") | (X X "a") ]', Fraction(0)),  # stay, then s3 -> s3
    ('Rmin=? [ X X "a" ]', Fraction(2)),  # stay, a: "a" surely at step 2
    ('Rmax=? [ F ("a" & (X s=3)) ]', math.inf),  # go: half never sees "a"
    ('Rmin=? [ F ("a" & (X s=3)) ]', Fraction(4)),  # 2 steps to s1, then 2 expected there
]


@pytest.mark.parametrize("exact", [False, True])
def test_optima_on_an_mdp(exact: bool) -> None:
    props = [text for text, _ in MDP_CASES]
    found = _values(MDP, props, exact=exact)
    for (text, want), got in zip(MDP_CASES, found, strict=True):
        if want == math.inf:
            assert got == math.inf or (exact and got is None), text
        elif exact:
            assert got == want, text
        else:
            assert math.isclose(got, float(want), abs_tol=1e-12), text


#: (reward path, "a" from s0, as PRISM's cosafety tests give it).
COSAFE_CASES = [
    ("X true", 5), ("X X true", 17), ("X X X true", 28), ("X X X false", math.inf),
    ("! (X true)", math.inf), ("! (X false)", 5), ("(X X true) U s=0", 0),
    ("(X X true) U s=1", 17), ("(X X true) U s=2", 28), ("(X X true) U s=3", 28),
    ("s=0 | (X true)", 0), ("F (X s=1)", 5), ("F (X s=3)", 28), ("F (s=1 & (X s=2))", 17),
]


@pytest.mark.parametrize("exact", [False, True])
def test_cosafe_rewards_settle_every_proposition_by_reading_it(exact: bool) -> None:
    props = [f'R{{"a"}}=? [ {path} ]' for path, _ in COSAFE_CASES]
    props.append('R{"b"}=? [ (X X true) U s=3 ]')  # waits for the last X X true: 58
    found = _values(LINE, props, exact=exact)
    wants = [want for _, want in COSAFE_CASES] + [58]
    for text, want, got in zip(props, wants, found, strict=True):
        if want == math.inf:
            assert got in (math.inf, None), text
        else:
            assert got == want, text


def test_from_other_states_through_a_filter() -> None:
    props = ['filter(state, R{"a"}=? [ s=0 | (X true) ], s=1)',
             'filter(state, R{"a"}=? [ (X s=1) | (X s=2) ], s=2)',
             'filter(state, P=? [ G F "a" ], s=3)']
    assert _values(LINE, props[:2], exact=False) == [12, math.inf]
    assert _values(CHAIN, props[2:], exact=False) == [1]


@pytest.mark.parametrize("path", ["G F s=1", "F G s=1", "s=0 W s=1", "! (F s=1)"])
def test_a_reward_path_that_is_not_cosafe_is_refused(path: str) -> None:
    with pytest.raises(CheckError, match="must be co-safe LTL"):
        check_prism_file(LINE, props_source=f'R{{"a"}}=? [ {path} ]')


def test_more_propositions_than_a_letter_holds_are_refused() -> None:
    formula = " & ".join(f"(F s={i})" for i in range(63))
    with pytest.raises(CheckError, match="63 distinct state formulas: at most 62"):
        check_prism_file(CHAIN, props_source=f"P=? [ {formula} ]")


def test_the_automaton_reads_only_the_letters_the_model_shows() -> None:
    """Ten propositions that never hold together: eleven letters, not 1,024 (visiting ten
    states in any order needs 2^10 automaton states; each reads eleven letters)."""
    ring = ("dtmc\nmodule m\n  s : [0..15] init 0;\n"
            "  [] true -> 0.5:(s'=mod(s+1,16)) + 0.5:(s'=mod(s+3,16));\nendmodule\n")
    formula = " & ".join(f"(F s={i})" for i in range(1, 11))
    (result,) = check_prism_file(ring, props_source=f"P=? [ {formula} ]").results
    assert result.value == 1.0 and result.lower == 1.0


@pytest.mark.parametrize(("query", "want"), [
    # From s3, staying forever (F G s=3) and returning to s1 for ever (G F "a") exclude
    # each other: a strategy that stays with probability x meets them with x and 1 - x.
    ('multi(Pmax=? [ F G s=3 ], P>=0.3 [ G F "a" ])', 0.7),
    ('multi(P>=0.65 [ F G s=3 ], P>=0.3 [ G F "a" ])', True),
    ('multi(P>=0.8 [ F G s=3 ], P>=0.3 [ G F "a" ])', False),
    ('multi(Pmax=? [ G F "a" ], P>=0.25 [ F G s=3 ], P>=0.5 [ F s=3 ])', 0.75),
])
def test_ltl_objectives_in_multi(query: str, want: object) -> None:
    (result,) = check_prism_file(MDP, props_source=query).results
    if isinstance(want, bool):
        assert result.value is want
    else:
        assert math.isclose(result.value, want, abs_tol=1e-6)


@pytest.mark.parametrize(("text", "says"), [
    ('Pmax=? [ G F "a" ]', "an optimal strategy for LTL needs the automaton's state"),
    ('Rmin=? [ F ("a" & (X s=3)) ]', "an optimal strategy for LTL needs the automaton's state"),
    ('multi(Pmax=? [ F "a" ], P>=0.5 [ G F "a" ])', "an LTL objective in multi(...) needs"),
])
def test_a_strategy_for_ltl_is_refused_before_the_build(text: str, says: str) -> None:
    refusal = strategy_refusal(parse_property(text).formula)
    assert refusal is not None and says in str(refusal)


@pytest.mark.parametrize("operator", ["P=?", 'R{"steps"}=?'])
def test_a_formula_nested_thousands_deep_is_one_error(operator: str) -> None:
    formula = "X " * 3000 + '"a"'
    with pytest.raises(CheckError, match="nests its operators too deeply"):
        check_prism_file(CHAIN, props_source=f"{operator} [ {formula} ]")
