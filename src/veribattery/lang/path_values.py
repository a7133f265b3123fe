"""What the property rules pass up before it becomes a node: path formulas under way.

A temporal operator is a path formula, valid only inside a ``P``, ``R``, ``A`` or ``E``
operator. One temporal operator over state formulas stays a :class:`Temporal` (the
operators' own PCTL forms: ``F phi``, ``a U<=k b`` ...); nested in another one or in a
connective (``G F a``, ``(F a) & (G b)``) it becomes LTL (:mod:`veribattery.lang.nodes.ltl`).
Anything else -- a path formula inside arithmetic, a comparison, a filter -- is an
:class:`Unsupported` marker, kept with its reason up to the enclosing property.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TypeAlias, cast

from veribattery.errors import Span
from veribattery.lang.nodes import (
    Expr,
    LtlBinary,
    LtlNode,
    LtlNot,
    LtlOperand,
    LtlTemporal,
    TimeBound,
    TimeInterval,
)
from veribattery.lang.nodes.ltl import LtlConnective, LtlOperator

__all__ = ["LTL_CONNECTIVES", "TEMPORAL_NAMES", "Temporal", "Unsupported", "Value",
           "first_bad", "is_ltl", "is_path", "ltl_connective", "ltl_temporal"]

TEMPORAL_NAMES = {
    "X": "X (next)", "F": "F (eventually)", "G": "G (globally)", "U": "U (until)",
    "W": "W (weak until)", "R": "R (release)", "RB": "F or U with a reward bound",
}
#: The connectives that combine path formulas (PRISM's LTL).
LTL_CONNECTIVES = frozenset({"!", "&", "|", "=>", "<=>"})
_LTL_OPERATORS = frozenset({"X", "F", "G", "U", "W", "R"})


@dataclass(frozen=True, slots=True)
class Unsupported:
    """A construct that parses but is outside the supported language."""

    reason: str
    span: Span


@dataclass(frozen=True, slots=True)
class Temporal:
    """One temporal operator over state formulas: the whole path of a P, R, A or E
    operator, or a part of an LTL formula."""

    op: str
    bound: TimeBound | TimeInterval | None
    left: Expr | None
    right: Expr
    span: Span
    #: The reward structure of a reward bound (Storm's ``F{"r"}<=T``), else None.
    reward: str | int | None = None


Value: TypeAlias = Expr | Temporal | LtlNode | Unsupported


def is_path(value: object) -> bool:
    """Whether *value* is a path formula (a temporal operator or LTL over them)."""
    return isinstance(value, Temporal) or is_ltl(value)


def is_ltl(value: object) -> bool:
    """Whether *value* is LTL: more than one temporal operator over state formulas."""
    return isinstance(value, LtlNot | LtlBinary | LtlTemporal)


def first_bad(values: list[Any]) -> Unsupported | None:
    """The first unsupported operand; a path formula where a state formula or a number
    must be is one."""
    for value in values:
        if isinstance(value, Unsupported):
            return value
        if is_path(value):
            name = TEMPORAL_NAMES[value.op] if isinstance(value, Temporal | LtlTemporal) \
                else "a path formula"
            return Unsupported(
                f"temporal operator {name} inside an operator that takes a state formula or "
                "a number (path formulas combine with !, &, |, => and <=> only, inside P, "
                "R, A or E)", value.span)
    return None


def ltl_connective(op: str, operands: list[Any], span: Span) -> Value:
    """``!a``, ``a & b`` ... where an operand is a path formula: an LTL node."""
    parts = _ltl_operands(operands)
    if isinstance(parts, Unsupported):
        return parts
    if op == "!":
        return LtlNot(cast(LtlOperand, parts[0]), span)
    return LtlBinary(cast(LtlConnective, op), cast(LtlOperand, parts[0]),
                     cast(LtlOperand, parts[1]), span)


def ltl_temporal(op: str, bound: Any, left: Any, right: Any, span: Span) -> Value:
    """A temporal operator over a path formula (``G F a``, ``(X a) U b``): an LTL node."""
    bad = _first_unsupported([left, right, bound])
    if bad is not None:
        return bad
    if bound is not None:
        return Unsupported(f"a step bound on {TEMPORAL_NAMES[op]} over a path formula (LTL "
                           "takes unbounded operators only)", span)
    parts = _ltl_operands([left, right])
    if isinstance(parts, Unsupported):
        return parts
    return LtlTemporal(cast(LtlOperator, op), parts[0],
                       cast(LtlOperand, parts[1]), span)


def _ltl_operands(values: list[Any]) -> list[LtlOperand | None] | Unsupported:
    """*values* as LTL operands (None stays None), or the first that cannot be one."""
    bad = _first_unsupported(values)
    if bad is not None:
        return bad
    parts = [None if value is None else _ltl_operand(value) for value in values]
    return next((part for part in parts if isinstance(part, Unsupported)),
                cast("list[LtlOperand | None]", parts))


def _ltl_operand(value: Any) -> LtlOperand | Unsupported:
    if not isinstance(value, Temporal):
        return cast(LtlOperand, value)
    if value.op not in _LTL_OPERATORS:
        return Unsupported(f"{TEMPORAL_NAMES[value.op]} inside an LTL formula is not "
                           "supported", value.span)
    if value.bound is not None:
        return Unsupported(f"a step bound on {TEMPORAL_NAMES[value.op]} inside an LTL "
                           "formula (LTL takes unbounded operators only)", value.span)
    return LtlTemporal(cast(LtlOperator, value.op), value.left, value.right, value.span)


def _first_unsupported(values: list[Any]) -> Unsupported | None:
    return next((v for v in values if isinstance(v, Unsupported)), None)
