"""State-expression nodes: literals, identifiers, labels, operators, ``? :`` and calls."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal, TypeAlias

from veribattery.errors import NO_SPAN, Span

if TYPE_CHECKING:
    from veribattery.lang.nodes.pctl import Expr

__all__ = [
    "Binary",
    "BinaryOp",
    "BoolLit",
    "Call",
    "DoubleLit",
    "FunctionName",
    "Ident",
    "IntLit",
    "Ite",
    "LabelRef",
    "Unary",
    "UnaryOp",
    "Value",
    "ValueType",
]

# ---------------------------------------------------------------------------
# Expressions (state expressions; P/R operators are expressions too, so that
# they nest inside boolean connectives in property files)
# ---------------------------------------------------------------------------

ValueType: TypeAlias = Literal["int", "double", "bool"]
Value: TypeAlias = int | float | bool


@dataclass(frozen=True, slots=True)
class IntLit:
    """An integer literal."""

    value: int
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class DoubleLit:
    """A double literal; *text* keeps the digits as written (for exact re-printing)."""

    value: float
    text: str = ""
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class BoolLit:
    """``true`` or ``false``."""

    value: bool
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Ident:
    """A name: a variable, constant or formula (resolved by semantic analysis)."""

    name: str
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class LabelRef:
    """A quoted label in a property: ``"success"``, ``"init"``, ``"deadlock"``."""

    name: str
    span: Span = field(default=NO_SPAN, compare=False)


UnaryOp: TypeAlias = Literal["!", "-"]
BinaryOp: TypeAlias = Literal[
    "|", "&", "=>", "<=>", "=", "!=", "<", "<=", ">", ">=", "+", "-", "*", "/"
]


@dataclass(frozen=True, slots=True)
class Unary:
    """``!a`` or ``-a``."""

    op: UnaryOp
    operand: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Binary:
    """``a op b`` for the boolean, relational and arithmetic operators."""

    op: BinaryOp
    left: Expr
    right: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Ite:
    """``cond ? then : otherwise``."""

    cond: Expr
    then: Expr
    otherwise: Expr
    span: Span = field(default=NO_SPAN, compare=False)


FunctionName: TypeAlias = Literal["min", "max", "floor", "ceil", "pow", "mod", "log", "round"]


@dataclass(frozen=True, slots=True)
class Call:
    """A built-in function: ``min max floor ceil pow mod log round`` (``func(f, ...)`` too)."""

    func: FunctionName
    args: tuple[Expr, ...]
    span: Span = field(default=NO_SPAN, compare=False)
