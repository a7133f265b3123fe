"""LTL path formulas: temporal operators nested in each other or in connectives.

PRISM reads a ``P``, ``A`` or ``E`` operator's path as LTL whenever it is more than one
temporal operator over state formulas (``G F "goal"``, ``(F a) & (G b)``, ``F (a & X b)``),
and an ``R`` operator's path as co-safe LTL (``R [ F (X s=1) ]``). The leaves of the tree
are state formulas (:data:`~veribattery.lang.nodes.Expr`, operators included); the checker
evaluates each to a set of states and reads the tree through an automaton.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal, TypeAlias

from veribattery.errors import NO_SPAN, Span

if TYPE_CHECKING:
    from veribattery.lang.nodes.pctl import Expr

__all__ = ["CosafeReach", "LtlBinary", "LtlNode", "LtlNot", "LtlOperand", "LtlPath",
           "LtlTemporal"]

LtlConnective: TypeAlias = Literal["&", "|", "=>", "<=>"]
LtlOperator: TypeAlias = Literal["X", "F", "G", "U", "W", "R"]


@dataclass(frozen=True, slots=True)
class LtlNot:
    """``!phi`` over a path formula."""

    operand: LtlOperand
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class LtlBinary:
    """``left & right``, ``|``, ``=>`` or ``<=>`` with a path formula on either side."""

    op: LtlConnective
    left: LtlOperand
    right: LtlOperand
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class LtlTemporal:
    """``X phi``, ``F phi``, ``G phi`` (*left* None) or ``left U/W/R right``, unbounded."""

    op: LtlOperator
    left: LtlOperand | None
    right: LtlOperand
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class LtlPath:
    """The path of a ``P``, ``A`` or ``E`` operator, read as LTL."""

    formula: LtlNode
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class CosafeReach:
    """Reward path of co-safe LTL: the reward accumulated until *formula* is satisfied
    (the first prefix all of whose continuations satisfy it), infinite from a state where
    that is not almost sure."""

    formula: LtlNode
    span: Span = field(default=NO_SPAN, compare=False)


LtlNode: TypeAlias = LtlNot | LtlBinary | LtlTemporal
LtlOperand: TypeAlias = "LtlNode | Expr"
