"""Evaluation of closed expressions with PRISM's semantics (constants, bounds, folding).

ints stay exact Python ints; ``/`` always gives a double; ``floor``/``ceil`` give
ints; ``pow`` and ``mod`` of ints are ints; ``min``/``max`` are int iff all
arguments are; ``mod`` is non-negative for a positive divisor, as in PRISM.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

from veribattery.errors import PrismSemanticError
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    DoubleLit,
    Expr,
    Ident,
    IntLit,
    Ite,
    Unary,
    Value,
)


class EvaluationError(PrismSemanticError):
    """An expression has no value: not constant, or an arithmetic error."""


def evaluate(expr: Expr, values: Mapping[str, Value]) -> Value:
    """The value of *expr*, whose identifiers must all be in *values*.

    :raises EvaluationError: for an unknown name or an arithmetic error
    """
    if isinstance(expr, IntLit | DoubleLit | BoolLit):
        return expr.value
    if isinstance(expr, Ident):
        if expr.name not in values:
            raise EvaluationError(f"'{expr.name}' is not a constant", expr.span)
        return values[expr.name]
    if isinstance(expr, Unary):
        operand = evaluate(expr.operand, values)
        return (not operand) if expr.op == "!" else -operand
    if isinstance(expr, Binary):
        return _binary(expr, values)
    if isinstance(expr, Ite):
        branch = expr.then if evaluate(expr.cond, values) else expr.otherwise
        return evaluate(branch, values)
    if isinstance(expr, Call):
        args = [evaluate(a, values) for a in expr.args]
        return _call(expr, args)
    raise EvaluationError("this expression has no constant value", expr.span)


def _divide(a: Value, b: Value) -> float:
    # Java double division: x/0 is +-Infinity, 0/0 is NaN (PRISM does not fail).
    if b == 0:
        return math.nan if a == 0 else math.copysign(math.inf, a) * math.copysign(1.0, b)
    return a / b


_ARITH: dict[str, Callable[[Value, Value], Value]] = {
    "+": lambda a, b: a + b,
    "-": lambda a, b: a - b,
    "*": lambda a, b: a * b,
    "/": _divide,
    "=": lambda a, b: a == b,
    "!=": lambda a, b: a != b,
    "<": lambda a, b: a < b,
    "<=": lambda a, b: a <= b,
    ">": lambda a, b: a > b,
    ">=": lambda a, b: a >= b,
    "=>": lambda a, b: (not a) or bool(b),
    "<=>": lambda a, b: bool(a) == bool(b),
}


def _binary(expr: Binary, values: Mapping[str, Value]) -> Value:
    left = evaluate(expr.left, values)
    # & and | short-circuit, so "x!=0 & 1/x>2" never divides by zero.
    if expr.op == "&":
        return bool(left) and bool(evaluate(expr.right, values))
    if expr.op == "|":
        return bool(left) or bool(evaluate(expr.right, values))
    result: Value = _ARITH[expr.op](left, evaluate(expr.right, values))
    return result


def prism_mod(i: int, n: int) -> int:
    """PRISM's ``mod``: Java's remainder, shifted up by *n* when negative."""
    if n == 0:
        raise ZeroDivisionError("mod by zero")
    rem = abs(i) % abs(n) * (1 if i >= 0 else -1)
    return rem + n if rem < 0 else rem


def _pow(base: Value, exp: Value) -> Value:
    if isinstance(base, int) and isinstance(exp, int):
        if exp < 0:
            raise ValueError("negative exponent in an integer pow")
        return int(base**exp)
    return math.pow(base, exp)


def _log(x: Value, base: Value) -> float:
    try:
        return math.log(x) / math.log(base)
    except (ValueError, ZeroDivisionError):
        return math.nan


def _extreme(pick: Callable[..., Value], args: Sequence[Value]) -> Value:
    value = pick(args)
    return value if all(isinstance(a, int) for a in args) else float(value)


_FUNCTIONS: dict[str, Callable[[Sequence[Value]], Value]] = {
    "min": lambda a: _extreme(min, a),
    "max": lambda a: _extreme(max, a),
    "floor": lambda a: math.floor(a[0]),
    "ceil": lambda a: math.ceil(a[0]),
    "pow": lambda a: _pow(a[0], a[1]),
    "mod": lambda a: prism_mod(int(a[0]), int(a[1])),
    "log": lambda a: _log(a[0], a[1]),
}


def _call(expr: Call, args: Sequence[Value]) -> Value:
    try:
        result: Value = _FUNCTIONS[expr.func](args)
        return result
    except (ValueError, ZeroDivisionError, OverflowError) as exc:
        raise EvaluationError(f"cannot evaluate {expr.func}(...): {exc}", expr.span) from None
