"""The formula recursion and the check() facade, on hand-built DTMCs."""

from __future__ import annotations

import numpy as np
import pytest

from tests.checker.chains import dtmc, gamblers_ruin, knuth_die
from veribattery.checker import CheckResult, check, state_set, values
from veribattery.checker.certify.bounds import Bounds
from veribattery.errors import CheckError, Span
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Cumulative,
    DoubleLit,
    Eventually,
    Expr,
    Globally,
    Ident,
    Instantaneous,
    IntLit,
    LabelRef,
    Next,
    ProbOp,
    Property,
    Reach,
    RewardOp,
    TimeBound,
    Unary,
    Until,
)

HERE = Span(3, 7, "props.pctl")


def L(name: str) -> LabelRef:
    return LabelRef(name, span=HERE)


def P(path: object, op: str = "=?", bound: float | None = None) -> ProbOp:
    return ProbOp(op, None if bound is None else DoubleLit(bound), path,  # type: ignore[arg-type]
                  span=HERE)


def R(path: object, reward: str | int | None = None, op: str = "=?",
      bound: float | None = None) -> RewardOp:
    return RewardOp(reward, op, None if bound is None else DoubleLit(bound), path,  # type: ignore[arg-type]
                    span=HERE)


def le(k: int) -> TimeBound:
    return TimeBound("<=", IntLit(k))


def NOT(e: Expr) -> Unary:
    return Unary("!", e)


# One state per row: (formula, expected value at state 0). 0 stays with 1/2 or moves to
# the absorbing "bad" state 1; rewards: state 1 and transition 2 in 0, state 10 in 1.
GEOMETRIC = dtmc({0: {0: 0.5, 1: 0.5}}, 2, labels={"good": [0], "bad": [1]},
                 rewards={"r": ([1.0, 10.0], [2.0, 0.0])})
GEOMETRIC_CASES = {
    "X bad": (P(Next(L("bad"))), 0.5),
    "F bad": (P(Eventually(L("bad"))), 1.0),
    "G good": (P(Globally(L("good"))), 0.0),
    "G<=3 good": (P(Globally(L("good"), le(3))), 0.125),
    "G<3 good": (P(Globally(L("good"), TimeBound("<", IntLit(3)))), 0.25),
    "F<=2 bad": (P(Eventually(L("bad"), le(2))), 0.75),
    "F<0 bad": (P(Eventually(L("bad"), TimeBound("<", IntLit(0)))), 0.0),
    "good U<=1 bad": (P(Until(L("good"), L("bad"), le(1))), 0.5),
    "F>=2 good": (P(Eventually(L("good"), TimeBound(">=", IntLit(2)))), 0.25),
    "F>1 good": (P(Eventually(L("good"), TimeBound(">", IntLit(1)))), 0.25),
    "G>=1 bad": (P(Globally(L("bad"), TimeBound(">=", IntLit(1)))), 0.5),
    "R C<=2": (R(Cumulative(IntLit(2)), "r"), 3.0 + 0.5 * 3 + 0.5 * 10),
    "R C<=0": (R(Cumulative(IntLit(0)), "r"), 0.0),
    "R I=2": (R(Instantaneous(IntLit(2))), 0.25 + 0.75 * 10),
    "R F bad": (R(Reach(L("bad")), 0), 6.0),
    "R F good": (R(Reach(L("good"))), 0.0),
    "P>=0.5 X bad": (P(Next(L("bad")), ">=", 0.5), True),
    "P>0.5 X bad": (P(Next(L("bad")), ">", 0.5), False),
    "R<7 F bad": (R(Reach(L("bad")), op="<", bound=7), True),
    "good & P>0.9 F bad": (Binary("&", L("good"), P(Eventually(L("bad")), ">", 0.9)), True),
    "bad | P<0.1 X bad": (Binary("|", L("bad"), P(Next(L("bad")), "<", 0.1)), False),
    "P>0.9 [F P>=1 [G bad]]": (P(Eventually(P(Globally(L("bad")), ">=", 1.0)), ">", 0.9), True),
    "!good => P<=0.5 X bad": (Binary("=>", NOT(L("good")), P(Next(L("bad")), "<=", 0.5)),
                              True),
    "init <=> good": (Binary("<=>", L("init"), L("good")), True),
    "true": (BoolLit(True), True),
}


@pytest.mark.parametrize("name", GEOMETRIC_CASES)
def test_geometric_chain(name: str) -> None:
    formula, expected = GEOMETRIC_CASES[name]
    result = check(GEOMETRIC, formula)
    if isinstance(expected, bool):
        assert result.value is expected
    else:
        assert result.value == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_die_through_check() -> None:
    die = knuth_die()
    for face in range(1, 7):
        assert check(die, P(Eventually(L(f"face{face}")))).value == pytest.approx(1 / 6)
    flips = check(die, Property(R(Reach(L("done")), "flips"), name="flips", text='R=?[F "done"]'))
    assert flips.value == pytest.approx(11 / 3, rel=1e-12)
    assert flips.property.name == "flips"
    assert str(flips).startswith("flips: 3.666")
    assert flips.time_s >= 0


def test_variable_expressions_use_compiled_leaves() -> None:
    # s is the state index in these chains: F s>=20 on gambler's ruin(20) is "win".
    chain = gamblers_ruin(20, 0.4)
    target = Binary(">=", Ident("s"), IntLit(20))
    by_var = values(chain, P(Eventually(target)))
    by_label = values(chain, P(Eventually(L("win"))))
    assert by_var.value.tolist() == by_label.value.tolist()
    assert state_set(chain, Binary("<", Ident("s"), IntLit(3))).tolist() == [
        i < 3 for i in range(21)
    ]


def test_boolean_variable_as_state_formula() -> None:
    # Boolean variables are stored as 0/1 integers in the state table.
    chain = dtmc({0: {0: 0.5, 1: 0.5}}, 2, variable_names=("b",))
    assert check(chain, P(Eventually(Ident("b")))).value == 1.0
    assert check(chain, P(Next(Unary("!", Ident("b"))))).value == 0.5


def test_values_of_plain_numeric_expression() -> None:
    chain = gamblers_ruin(4, 0.5)
    result = values(chain, Binary("*", Ident("s"), IntLit(2)))
    assert isinstance(result, Bounds)
    assert result.value.dtype == np.float64
    assert result.value.tolist() == [0, 2, 4, 6, 8]
    assert result.lower.tolist() == result.upper.tolist() == [0, 2, 4, 6, 8]


# --- initial states -----------------------------------------------------------------


def test_multiple_initial_states() -> None:
    chain = gamblers_ruin(10, 0.5, initial=(3, 7))
    numeric = check(chain, P(Eventually(L("win"))))
    assert numeric.value == pytest.approx(0.3)  # the first initial state
    assert check(chain, P(Eventually(L("win")), ">", 0.2)).value is True
    assert check(chain, P(Eventually(L("win")), ">", 0.5)).value is False  # not in all
    assert check(chain, L("init")).value is True


def test_no_initial_state_is_an_error() -> None:
    chain = dtmc({}, 2, initial=())
    with pytest.raises(CheckError, match="no initial state"):
        check(chain, BoolLit(True))


def test_check_result_is_frozen() -> None:
    result = check(GEOMETRIC, BoolLit(True))
    assert isinstance(result, CheckResult)
    with pytest.raises(AttributeError):
        result.value = False  # type: ignore[misc]


# --- errors say where --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("formula", "message"),
    [
        (P(Eventually(L("missing"))), 'unknown label "missing"'),
        (R(Reach(L("bad")), "nope"), "no reward structure 'nope'"),
        (R(Reach(L("bad")), 5), "no reward structure 5"),
        (Binary("&", L("good"), P(Next(L("bad"))), span=HERE), "query"),
        (P(Eventually(L("bad"), TimeBound("<=", DoubleLit(1.5, span=HERE)))), "integer"),
        (P(Eventually(L("bad"), TimeBound("<=", Ident("k", span=HERE)))), "numeric constant"),
        (Binary("+", IntLit(1), P(Next(L("bad")), ">", 0.5), span=HERE), "needs numbers"),
        (P(Eventually(Binary("+", Ident("s"), IntLit(1), span=HERE))), "boolean"),
    ],
    ids=lambda case: case if isinstance(case, str) else "",
)
def test_errors_carry_the_span(formula: Expr, message: str) -> None:
    with pytest.raises(CheckError, match=message) as info:
        check(GEOMETRIC, formula)
    assert info.value.span == HERE
    assert str(info.value).startswith("props.pctl:3:7: ")


def test_model_without_rewards() -> None:
    chain = dtmc({}, 1)
    with pytest.raises(CheckError, match="no reward structure"):
        check(chain, R(Cumulative(IntLit(1))))
