"""LTL path formulas parse into :mod:`veribattery.lang.nodes.ltl` nodes.

One temporal operator over state formulas keeps its PCTL node (``F``, ``U`` ...); nested in
another or in a connective it is LTL, in the P, A and E operators (``LtlPath``) and, as
co-safe LTL, in R (``CosafeReach``). Both parsers (the fast one and lark) build them.
"""

from __future__ import annotations

import pytest

from veribattery.lang.nodes import (
    BoolLit,
    CosafeReach,
    Eventually,
    LabelRef,
    LtlBinary,
    LtlNot,
    LtlPath,
    LtlTemporal,
    ProbOp,
    Quantified,
    RewardOp,
)
from veribattery.lang.parser import parse_property


def test_nested_temporal_operators_are_ltl() -> None:
    formula = parse_property('P=? [ G F "a" ]').formula
    assert isinstance(formula, ProbOp)
    assert formula.path == LtlPath(
        LtlTemporal("G", None, LtlTemporal("F", None, LabelRef("a"))))


def test_connectives_over_path_formulas_are_ltl() -> None:
    formula = parse_property('Pmax=? [ !(F "a") | ((X "b") & true) ]').formula
    assert isinstance(formula, ProbOp) and formula.direction == "max"
    assert formula.path == LtlPath(LtlBinary(
        "|", LtlNot(LtlTemporal("F", None, LabelRef("a"))),
        LtlBinary("&", LtlTemporal("X", None, LabelRef("b")), BoolLit(True))))


def test_one_temporal_operator_keeps_its_pctl_node() -> None:
    formula = parse_property('P=? [ F "a" ]').formula
    assert isinstance(formula, ProbOp) and formula.path == Eventually(LabelRef("a"))


@pytest.mark.parametrize(("text", "op"), [("A [ G F \"a\" ]", "A"), ("E [ F G \"a\" ]", "E")])
def test_path_quantifiers_take_ltl(text: str, op: str) -> None:
    formula = parse_property(text).formula
    assert isinstance(formula, Quantified) and formula.quantifier == op
    assert isinstance(formula.path, LtlPath)


@pytest.mark.parametrize("path", ['F (X "a")', '(X X true) U "a"', '"a" | (X "b")', 'G "a"'])
def test_reward_paths_beyond_one_operator_are_cosafe_reach(path: str) -> None:
    formula = parse_property(f"R=? [ {path} ]").formula
    assert isinstance(formula, RewardOp) and isinstance(formula.path, CosafeReach)


def test_spans_point_at_the_operators() -> None:
    formula = parse_property('P=? [ (F "a") & (G "b") ]').formula
    assert isinstance(formula, ProbOp) and isinstance(formula.path, LtlPath)
    node = formula.path.formula
    assert isinstance(node, LtlBinary)
    assert (node.left.span.col, node.right.span.col) == (8, 18)  # type: ignore[union-attr]
