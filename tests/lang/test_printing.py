"""Printed PRISM text reads back as the tree it came from, with precedence explicit."""

from __future__ import annotations

import pytest

from veribattery.lang import parse_property
from veribattery.lang.nodes import ProbOp, RewardOp
from veribattery.lang.printing import expression_text, path_text, reward_path_text

PATHS = [
    ('F "goal"', 'F "goal"'),
    ("x<2 U x=3 | !b", "(x < 2) U ((x = 3) | (!b))"),
    # PRISM's precedence: <=> binds tighter than =>.
    ("F a & b | c => d <=> e", "F (((a & b) | c) => (d <=> e))"),
    ("G<=5 1-2-3 > -x", "G<=5 (((1 - 2) - 3) > (-x))"),
    ("F x>0 ? y/2 : max(y, 3)*2 >= 0.5", "F ((x > 0) ? (y / 2) : ((max(y, 3) * 2) >= 0.5))"),
    ("a W[2,4] b", "a W[2,4] b"),
    ('"l" R>=3 pow(x, 2)=mod(y, 3)', '"l" R>=3 (pow(x, 2) = mod(y, 3))'),
    ("X floor(1.25e-3*x)!=ceil(x)", "X (floor((0.00125 * x)) != ceil(x))"),
    ("true U=4 t=1", "true U=4 (t = 1)"),
]


@pytest.mark.parametrize(("path", "expected"), PATHS, ids=[p for p, _ in PATHS])
def test_path_text_is_fully_parenthesised_and_reads_back(path: str, expected: str) -> None:
    formula = parse_property(f"P=? [ {path} ]").formula
    assert isinstance(formula, ProbOp)
    text = path_text(formula.path)
    assert text == expected
    again = parse_property(f"P=? [ {text} ]").formula
    assert isinstance(again, ProbOp)
    assert path_text(again.path) == text


@pytest.mark.parametrize(("path", "expected"), [
    ('F "done"', 'F "done"'), ("C", "C"), ("C<=10", "C<=10"), ("I=3", "I=3"),
])
def test_reward_paths(path: str, expected: str) -> None:
    formula = parse_property(f"R=? [ {path} ]").formula
    assert isinstance(formula, RewardOp)
    assert reward_path_text(formula.path) == expected


def test_negative_literals_keep_their_sign_in_parentheses() -> None:
    from veribattery.lang.nodes import Binary, DoubleLit, Ident, IntLit

    expr = Binary("+", Binary("*", IntLit(-3), Ident("x")), DoubleLit(-0.5))
    assert expression_text(expr) == "(((-3) * x) + (-0.5))"
