"""Evaluation of closed expressions with PRISM's semantics (constants, bounds, folding).

ints stay exact Python ints; ``/`` always gives a double; ``floor``/``ceil`` give
ints; ``pow`` and ``mod`` of ints are ints; ``min``/``max`` are int iff all
arguments are; ``mod`` is non-negative for a positive divisor, as in PRISM.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, cast

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

    ``&`` and ``|`` short-circuit, so ``x!=0 & 1/x>2`` never divides by zero, and
    ``? :`` evaluates only the branch it takes. The evaluation keeps its own stack:
    a constant may be a sum of thousands of terms.

    :raises EvaluationError: for an unknown name or an arithmetic error
    """
    results: list[Value] = []
    todo: list[tuple[int, Expr]] = [(_EVALUATE, expr)]
    while todo:
        step, node = todo.pop()
        if step == _EVALUATE:
            _start(node, values, results, todo)
        else:
            _STEPS[step](cast(Any, node), results, todo)
    return results[0]


# What is left to do for a node once some of its operands are on the results stack.
_EVALUATE, _NEGATE, _LEFT_DONE, _APPLY, _TRUTH, _CHOOSE, _CALL = range(7)


def _start(
    node: Expr, values: Mapping[str, Value], results: list[Value], todo: list[tuple[int, Expr]]
) -> None:
    """Push *node*'s value, or the steps that compute it."""
    if isinstance(node, IntLit | DoubleLit | BoolLit):
        results.append(node.value)
    elif isinstance(node, Ident):
        if node.name not in values:
            raise EvaluationError(f"'{node.name}' is not a constant", node.span)
        results.append(values[node.name])
    elif isinstance(node, Unary):
        todo += [(_NEGATE, node), (_EVALUATE, node.operand)]
    elif isinstance(node, Binary):
        todo += [(_LEFT_DONE, node), (_EVALUATE, node.left)]
    elif isinstance(node, Ite):
        todo += [(_CHOOSE, node), (_EVALUATE, node.cond)]
    elif isinstance(node, Call):
        todo.append((_CALL, node))
        todo += [(_EVALUATE, a) for a in reversed(node.args)]
    else:
        raise EvaluationError("this expression has no constant value", node.span)


def _negate(node: Unary, results: list[Value], todo: list[tuple[int, Expr]]) -> None:
    operand = results.pop()
    results.append((not operand) if node.op == "!" else -operand)


def _left_done(node: Binary, results: list[Value], todo: list[tuple[int, Expr]]) -> None:
    """The left operand is known: decide ``&``/``|`` by it, or evaluate the right one."""
    op = node.op
    if op in ("&", "|"):
        left = bool(results.pop())
        if left == (op == "|"):
            results.append(left)
            return
        todo += [(_TRUTH, node), (_EVALUATE, node.right)]
        return
    todo += [(_APPLY, node), (_EVALUATE, node.right)]


def _apply(node: Binary, results: list[Value], todo: list[tuple[int, Expr]]) -> None:
    right = results.pop()
    results.append(_ARITH[node.op](results.pop(), right))


def _truth(node: Expr, results: list[Value], todo: list[tuple[int, Expr]]) -> None:
    results.append(bool(results.pop()))


def _choose(node: Ite, results: list[Value], todo: list[tuple[int, Expr]]) -> None:
    todo.append((_EVALUATE, node.then if results.pop() else node.otherwise))


def _call_step(node: Call, results: list[Value], todo: list[tuple[int, Expr]]) -> None:
    count = len(node.args)
    args = results[len(results) - count :]
    del results[len(results) - count :]
    results.append(_call(node, args))


_STEPS: dict[int, Callable[[Any, list[Value], list[tuple[int, Expr]]], None]] = {
    _NEGATE: _negate,
    _LEFT_DONE: _left_done,
    _APPLY: _apply,
    _TRUTH: _truth,
    _CHOOSE: _choose,
    _CALL: _call_step,
}


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
