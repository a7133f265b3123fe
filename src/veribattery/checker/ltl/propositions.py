"""An LTL path formula as an automaton's formula over its maximal state subformulas.

Every maximal state subformula (``s=2``, ``"goal"``, ``P>0.5 [ F a ]``) becomes one atomic
proposition; equal subformulas (spans aside) share one. The checker evaluates each to a
set of states, and a state's letter is the set of propositions that hold there, as bits.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.checker.automata import formula as ltl
from veribattery.errors import CheckError
from veribattery.lang.nodes import BoolLit, Expr, LtlBinary, LtlNot, LtlOperand, LtlTemporal

__all__ = ["MAX_PROPOSITIONS", "Propositions", "letters", "propositions"]

#: A letter is the set of propositions that hold, as the bits of an int64.
MAX_PROPOSITIONS = 62


@dataclass(frozen=True, slots=True)
class Propositions:
    """The automaton's formula and the state formula of each of its propositions."""

    formula: ltl.LtlFormula
    operands: tuple[Expr, ...]


def propositions(node: LtlOperand) -> Propositions:
    """*node* over propositions ``0 .. k-1``, numbered in the order they are met.

    :raises CheckError: over :data:`MAX_PROPOSITIONS` distinct state subformulas.
    """
    found: dict[Expr, int] = {}
    formula = _translated(node, found)
    if len(found) > MAX_PROPOSITIONS:
        raise CheckError(f"an LTL formula over {len(found)} distinct state formulas: at most "
                         f"{MAX_PROPOSITIONS} are supported", getattr(node, "span", None))
    return Propositions(formula, tuple(found))


def letters(operands: Sequence[Expr], states: Callable[[Expr], BoolArray],
            num_states: int) -> IntArray:
    """Per state, the bits of the propositions that hold there (bit *i*: proposition *i*)."""
    letter = np.zeros(num_states, dtype=np.int64)
    for index, operand in enumerate(operands):
        letter |= states(operand).astype(np.int64) << index
    return letter


def _translated(node: LtlOperand, found: dict[Expr, int]) -> ltl.LtlFormula:
    match node:
        case LtlNot(operand=operand):
            return ltl.Not(_translated(operand, found))
        case LtlBinary(op=op, left=left, right=right):
            a, b = _translated(left, found), _translated(right, found)
            if op == "&":
                return ltl.And(a, b)
            if op == "|":
                return ltl.Or(a, b)
            return ltl.implies(a, b) if op == "=>" else ltl.iff(a, b)
        case LtlTemporal(op=op, left=left, right=right):
            return _temporal(op, None if left is None else _translated(left, found),
                             _translated(right, found))
        case BoolLit(value=value):
            return ltl.Const(value)
    return ltl.Prop(found.setdefault(node, len(found)))


def _temporal(op: str, left: ltl.LtlFormula | None, right: ltl.LtlFormula) -> ltl.LtlFormula:
    if op == "X":
        return ltl.Next(right)
    if op == "F":
        return ltl.eventually(right)
    if op == "G":
        return ltl.globally(right)
    assert left is not None
    if op == "U":
        return ltl.Until(left, right)
    if op == "W":
        return ltl.weak_until(left, right)
    return ltl.Release(left, right)
