"""Expressions and path formulas back to PRISM text, for files other tools read.

The text is fully parenthesised rather than minimal: it is written for PRISM, Storm
and this parser to read back with exactly the tree it came from, so precedence never
has to be trusted. Doubles are written with :func:`repr` (the shortest text that reads
back as the same double).
"""

from __future__ import annotations

from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    Cumulative,
    DoubleLit,
    Eventually,
    Expr,
    Globally,
    Ident,
    Instantaneous,
    IntLit,
    Ite,
    LabelRef,
    Next,
    PathFormula,
    Reach,
    Release,
    RewardPath,
    TimeBound,
    TimeInterval,
    Total,
    Unary,
    Until,
    WeakUntil,
)

__all__ = ["expression_text", "path_text", "reward_path_text"]


def expression_text(expr: Expr) -> str:
    """*expr* (a state expression without P/R operators) as PRISM text."""
    match expr:
        case BoolLit(value=value):
            return "true" if value else "false"
        case IntLit(value=value):
            return str(value) if value >= 0 else f"({value})"
        case DoubleLit(value=value):
            return repr(float(value)) if value >= 0 else f"({float(value)!r})"
        case Ident(name=name):
            return name
        case LabelRef(name=name):
            return f'"{name}"'
        case Unary(op=op, operand=operand):
            return f"({op}{expression_text(operand)})"
        case Binary(op=op, left=left, right=right):
            return f"({expression_text(left)} {op} {expression_text(right)})"
        case Ite(cond=cond, then=then, otherwise=otherwise):
            return (f"({expression_text(cond)} ? {expression_text(then)} : "
                    f"{expression_text(otherwise)})")
        case Call(func=func, args=args):
            return f"{func}({', '.join(expression_text(a) for a in args)})"
    raise ValueError(f"no PRISM text for {type(expr).__name__}")


def path_text(path: PathFormula) -> str:
    """The path formula of a ``P`` operator as PRISM text (``F "goal"``, ``a U<=5 b``)."""
    match path:
        case Next(operand=operand):
            return f"X {expression_text(operand)}"
        case Eventually(operand=operand, bound=bound):
            return f"F{_bound_text(bound)} {expression_text(operand)}"
        case Globally(operand=operand, bound=bound):
            return f"G{_bound_text(bound)} {expression_text(operand)}"
        case Until(left=left, right=right, bound=bound):
            return _binary_path(left, "U", bound, right)
        case WeakUntil(left=left, right=right, bound=bound):
            return _binary_path(left, "W", bound, right)
        case Release(left=left, right=right, bound=bound):
            return _binary_path(left, "R", bound, right)
    raise ValueError(f"no PRISM text for {type(path).__name__}")


def reward_path_text(path: RewardPath) -> str:
    """The path of an ``R`` operator as PRISM text (``F "goal"``, ``C``, ``C<=5``, ``I=3``)."""
    match path:
        case Reach(target=target):
            return f"F {expression_text(target)}"
        case Total():
            return "C"
        case Cumulative(bound=bound):
            return f"C<={expression_text(bound)}"
        case Instantaneous(time=time):
            return f"I={expression_text(time)}"
    raise ValueError(f"no PRISM text for {type(path).__name__}")


def _binary_path(left: Expr, op: str, bound: TimeBound | TimeInterval | None,
                 right: Expr) -> str:
    return f"{expression_text(left)} {op}{_bound_text(bound)} {expression_text(right)}"


def _bound_text(bound: TimeBound | TimeInterval | None) -> str:
    match bound:
        case None:
            return ""
        case TimeBound(op=op, value=value):
            return f"{op}{expression_text(value)}"
        case TimeInterval(low=low, high=high):
            return f"[{expression_text(low)},{expression_text(high)}]"
    raise ValueError(f"no PRISM text for {type(bound).__name__}")
