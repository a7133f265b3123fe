"""Expressions evaluated in exact rational arithmetic, vectorised over valuations.

Numbers are :class:`gmpy2.mpq` (GMP rationals) held in numpy
object arrays, so each operator is one numpy call over all valuations at once
while every element is exact: a literal ``0.1`` is ``1/10`` (read from the
digits as written), ``/`` is rational division, and int and double values are
both rationals. Booleans are numpy bool arrays.

An expression is evaluated over its *distinct* valuations only (see
:func:`tabulate`): a probability that reads two small variables is computed a
few dozen times, whatever the number of states.

Operators without an exact rational value -- ``log``, ``pow`` with a
non-integer exponent -- raise :class:`~veribattery.errors.ModelError` naming the
expression, as do divisions by zero.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from fractions import Fraction
from typing import Any, TypeAlias

import numpy as np
from gmpy2 import mpq, mpz

from veribattery._types import IntArray
from veribattery.errors import ModelError, PrismSemanticError
from veribattery.explore.exact.rational_ops import BINARY, FUNCTIONS, as_objects, bools, power
from veribattery.lang import ops
from veribattery.lang.expressions import walk
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
    ValueType,
)
from veribattery.lang.ops import OperatorError

__all__ = [
    "ExactScalar",
    "ObjectArray",
    "closed_value",
    "evaluate_rational",
    "rational",
    "tabulate",
]

ObjectArray: TypeAlias = np.ndarray
#: An exact constant: an int (:class:`gmpy2.mpz`), a double (:class:`gmpy2.mpq`) or a bool.
ExactScalar: TypeAlias = mpz | mpq | bool


def rational(value: Value | Fraction | str) -> mpq:
    """*value* as an exact rational; a float is read from its shortest decimal (0.1 is 1/10)."""
    if isinstance(value, bool):
        raise TypeError("a boolean is not a number")
    if isinstance(value, int):
        return mpq(value)
    if isinstance(value, float):
        if not np.isfinite(value):
            raise ValueError(f"{value} has no exact rational value")
        value = repr(value)
    fraction = Fraction(value)
    return mpq(fraction.numerator, fraction.denominator)


# ---------------------------------------------------------------------------
# Tabulation over distinct valuations
# ---------------------------------------------------------------------------


def tabulate(
    expr: Expr,
    constants: Mapping[str, ExactScalar],
    columns: Mapping[str, tuple[int, bool]],
    states: IntArray,
    convert: Callable[[np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """Exact value of *expr* in each row of *states*, evaluated once per distinct valuation.

    :param constants: exact values of the model's constants.
    :param columns: each variable's column in *states* and whether it is a bool.
    :param states: one row per state.
    :param convert: applied to the table of distinct values before it is spread
        over the rows (e.g. to bools or machine integers); None keeps the
        object array of rationals.
    """
    names = sorted({n.name for n in walk(expr) if isinstance(n, Ident)} - constants.keys())
    if not names:
        scalar = evaluate_rational(expr, constants, {}, 1)
        table = scalar if convert is None else convert(scalar)
        return np.repeat(table, states.shape[0])
    unknown = [n for n in names if n not in columns]
    if unknown:
        raise PrismSemanticError(f"unknown identifier '{unknown[0]}'", expr.span)
    picked = states[:, [columns[n][0] for n in names]]
    first, inverse = _distinct_rows(picked)
    distinct = picked[first]
    env = {n: _column(distinct[:, i], columns[n][1]) for i, n in enumerate(names)}
    table = evaluate_rational(expr, constants, env, distinct.shape[0])
    return (table if convert is None else convert(table))[inverse]


def _distinct_rows(rows: IntArray) -> tuple[IntArray, IntArray]:
    """First occurrence of each distinct row and each row's index among them.

    Rows are packed into one integer key by mixed radix when the ranges allow
    (``np.unique`` over whole rows sorts them as bytes, an order of magnitude slower).
    """
    low = rows.min(axis=0)
    sizes = [int(s) for s in rows.max(axis=0) - low + 1]
    if int(np.prod(np.array(sizes, dtype=object))) >= 1 << 62:
        _, first, inverse = np.unique(rows, axis=0, return_index=True, return_inverse=True)
        return first, inverse.reshape(-1)
    key = np.zeros(rows.shape[0], dtype=np.int64)
    for column, size in enumerate(sizes):
        key = key * size + (rows[:, column] - low[column])
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    return first, inverse.reshape(-1)


def _column(values: IntArray, is_bool: bool) -> np.ndarray:
    if is_bool:
        return values.astype(bool)
    return as_objects([mpq(int(v)) for v in values])


# ---------------------------------------------------------------------------
# The evaluator
# ---------------------------------------------------------------------------


def evaluate_rational(
    expr: Expr,
    constants: Mapping[str, ExactScalar],
    variables: Mapping[str, np.ndarray],
    n: int,
    *,
    doubles: Collection[str] = (),
) -> np.ndarray:
    """*expr* evaluated exactly for *n* valuations (object array of mpq, or bools).

    The operators are those of :mod:`veribattery.lang.ops` (see
    :mod:`.rational_ops`); ``&``, ``|``, ``=>`` and ``? :`` evaluate an operand
    only on the valuations that need it.

    :param constants: exact constant values (scalars; an int constant is an
        :class:`gmpy2.mpz`, a double an :class:`gmpy2.mpq`).
    :param variables: per variable, an array of *n* values (mpq objects or bools).
    :param doubles: the variables of type double (the others are ints or bools).
    :raises ModelError: for an operation without an exact rational result.
    """
    return _Evaluator(constants, variables, n, frozenset(doubles)).run(expr)[0]


def closed_value(expr: Expr, constants: Mapping[str, ExactScalar]) -> tuple[Any, ValueType]:
    """The exact value of the closed *expr* (no variables) and its PRISM type.

    :raises ModelError: for an operation without an exact rational result.
    """
    values, kind = _Evaluator(constants, {}, 1).run(expr)
    return values[0], kind


#: A value on the evaluator's stack: its array and its PRISM type.
_Typed = tuple[np.ndarray, ValueType]


class _Evaluator:
    """One evaluation: constants are broadcast, sub-expressions see row subsets.

    It keeps its own stack of steps (each with the evaluator of its rows) and of
    values: an expression may be a chain of thousands of operators.
    """

    def __init__(
        self, constants: Mapping[str, ExactScalar], variables: Mapping[str, np.ndarray], n: int,
        doubles: frozenset[str] = frozenset(),
    ) -> None:
        self.constants = constants
        self.variables = variables
        self.n = n
        self.doubles = doubles

    def subset(self, mask: np.ndarray) -> _Evaluator:
        chosen = {k: v[mask] for k, v in self.variables.items()}
        return _Evaluator(self.constants, chosen, int(np.count_nonzero(mask)), self.doubles)

    def full(self, value: Any, kind: ValueType) -> _Typed:
        if kind == "bool":
            return np.full(self.n, bool(value), dtype=bool), kind
        return np.full(self.n, mpq(value), dtype=object), kind

    def run(self, expr: Expr) -> _Typed:
        values: list[_Typed] = []
        todo: list[_Step] = [(_EVALUATE, expr, self)]
        while todo:
            step, node, context = todo.pop()
            if step == _EVALUATE:
                context.start(node, values, todo)
            else:
                _STEPS[step](node, context, values, todo)
        return values[0]

    def start(self, expr: Expr, values: list[_Typed], todo: list[_Step]) -> None:
        """Push the value of *expr* on these rows, or the steps that compute it."""
        if isinstance(expr, IntLit):
            values.append(self.full(expr.value, "int"))
        elif isinstance(expr, DoubleLit):
            exact = rational(expr.text) if expr.text else rational(expr.value)
            values.append(self.full(exact, "double"))
        elif isinstance(expr, BoolLit):
            values.append(self.full(expr.value, "bool"))
        elif isinstance(expr, Ident):
            values.append(self._ident(expr))
        elif isinstance(expr, Unary):
            todo += [(_NEGATE, expr, self), (_EVALUATE, expr.operand, self)]
        elif isinstance(expr, Binary) and ops.BINARY[expr.op].lazy:
            todo += [(_LEFT_DONE, expr, self), (_EVALUATE, expr.left, self)]
        elif isinstance(expr, Binary):
            todo += [(_APPLY, expr, self), (_EVALUATE, expr.right, self),
                     (_EVALUATE, expr.left, self)]
        elif isinstance(expr, Ite):
            todo += [(_CHOOSE, expr, self), (_EVALUATE, expr.cond, self)]
        elif isinstance(expr, Call):
            todo.append((_CALL, expr, self))
            todo += [(_EVALUATE, a, self) for a in reversed(expr.args)]
        else:
            raise PrismSemanticError(
                f"{type(expr).__name__} has no exact rational value", expr.span)

    def _ident(self, expr: Ident) -> _Typed:
        if expr.name in self.variables:
            column = self.variables[expr.name]
            if column.dtype == bool:
                return column, "bool"
            return column, "double" if expr.name in self.doubles else "int"
        if expr.name in self.constants:
            value = self.constants[expr.name]
            return self.full(value, _constant_type(value))
        raise PrismSemanticError(f"unknown identifier '{expr.name}'", expr.span)


def _constant_type(value: ExactScalar) -> ValueType:
    if isinstance(value, bool | np.bool_):
        return "bool"
    return "int" if isinstance(value, int | mpz) else "double"


#: A step of :meth:`_Evaluator.run`: what to do, for which node, with what (the
#: evaluator of the rows, or what an operator kept between its operands).
_Step = tuple[int, Any, Any]
_EVALUATE, _NEGATE, _APPLY, _LEFT_DONE, _RIGHT_DONE, _CHOOSE, _BRANCHES_DONE, _CALL = range(8)


def _negate(expr: Unary, rows: _Evaluator, values: list[_Typed], todo: list[_Step]) -> None:
    operand, kind = values.pop()
    values.append((~bools(operand) if expr.op == "!" else -operand, kind))


def _apply(expr: Binary, rows: _Evaluator, values: list[_Typed], todo: list[_Step]) -> None:
    right, right_kind = values.pop()
    left, left_kind = values.pop()
    kind = ops.BINARY[expr.op].result((left_kind, right_kind)) or "double"
    values.append((_located(expr, BINARY[expr.op], left, right), kind))


def _left_done(expr: Binary, rows: _Evaluator, values: list[_Typed], todo: list[_Step]) -> None:
    """``&``, ``|``, ``=>``: the right operand only where the left does not decide."""
    left = bools(values.pop()[0])
    deciding = ops.decided_by(expr.op, True) is not None  # the left value that decides
    settled = left if deciding else ~left
    result = settled.copy() if ops.decided_by(expr.op, deciding) else np.zeros_like(settled)
    undecided = ~settled
    if undecided.any():
        todo += [(_RIGHT_DONE, expr, (result, undecided)),
                 (_EVALUATE, expr.right, rows.subset(undecided))]
    else:
        values.append((result, "bool"))


def _right_done(
    expr: Binary, kept: tuple[np.ndarray, np.ndarray], values: list[_Typed], todo: list[_Step],
) -> None:
    result, undecided = kept
    result[undecided] = bools(values.pop()[0])
    values.append((result, "bool"))


def _choose(expr: Ite, rows: _Evaluator, values: list[_Typed], todo: list[_Step]) -> None:
    pick = bools(values.pop()[0])
    todo += [(_BRANCHES_DONE, expr, (rows, pick)),
             (_EVALUATE, expr.otherwise, rows.subset(~pick)),
             (_EVALUATE, expr.then, rows.subset(pick))]


def _branches_done(
    expr: Ite, kept: tuple[_Evaluator, np.ndarray], values: list[_Typed], todo: list[_Step]
) -> None:
    rows, pick = kept
    low, low_kind = values.pop()
    high, high_kind = values.pop()
    kind = ops.conditional_type(high_kind, low_kind) or "double"
    out = np.empty(rows.n, dtype=bool if kind == "bool" else object)
    out[pick] = high
    out[~pick] = low
    values.append((out, kind))


def _call_step(expr: Call, rows: _Evaluator, values: list[_Typed], todo: list[_Step]) -> None:
    count = len(expr.args)
    args = values[len(values) - count :]
    del values[len(values) - count :]
    values.append(_call(expr, args))


_STEPS: dict[int, Callable[[Any, Any, list[_Typed], list[_Step]], None]] = {
    _NEGATE: _negate,
    _APPLY: _apply,
    _LEFT_DONE: _left_done,
    _RIGHT_DONE: _right_done,
    _CHOOSE: _choose,
    _BRANCHES_DONE: _branches_done,
    _CALL: _call_step,
}


def _call(expr: Call, args: list[_Typed]) -> _Typed:
    function = ops.FUNCTIONS[expr.func]
    kinds = [kind for _, kind in args]
    kind = function.result(kinds) or "double"
    arrays = [array for array, _ in args]
    if expr.func == "pow":
        return _located(expr, power, *arrays, kind == "int"), kind
    return _located(expr, FUNCTIONS[expr.func], *arrays), kind


def _located(expr: Binary | Call, apply: Callable[..., np.ndarray], *args: Any) -> np.ndarray:
    """*apply* to *args*, an error reported at *expr* (a function's written out)."""
    try:
        return apply(*args)
    except OperatorError as exc:
        where = f"{_text(expr)}: " if isinstance(expr, Call) else ""
        raise ModelError(f"{where}{exc}", expr.span) from None


def _text(expr: Expr) -> str:
    """*expr* written back in PRISM syntax, for error messages (children first, no
    recursion)."""
    done: dict[int, str] = {}
    stack: list[tuple[Expr, bool]] = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        parts = _text_parts(node)
        if not ready and parts:
            stack.append((node, True))
            stack.extend([(p, False) for p in reversed(parts)])
            continue
        done[id(node)] = _written(node, [done[id(p)] for p in parts])
    return done[id(expr)]


def _text_parts(expr: Expr) -> tuple[Expr, ...]:
    match expr:
        case Unary(operand=operand):
            return (operand,)
        case Binary(left=left, right=right):
            return (left, right)
        case Ite(cond=cond, then=then, otherwise=otherwise):
            return (cond, then, otherwise)
        case Call(args=args):
            return args
    return ()


def _written(expr: Expr, parts: list[str]) -> str:
    """*expr* in PRISM syntax, given its operands written."""
    match expr:
        case IntLit(value=value) | BoolLit(value=value):
            return str(value).lower() if isinstance(value, bool) else str(value)
        case DoubleLit(value=value, text=text):
            return text or repr(value)
        case Ident(name=name):
            return name
        case Unary(op=op):
            return f"{op}{parts[0]}"
        case Binary(op=op):
            return f"({parts[0]} {op} {parts[1]})"
        case Ite():
            return f"({parts[0]} ? {parts[1]} : {parts[2]})"
        case Call(func=func):
            return f"{func}({', '.join(parts)})"
    return type(expr).__name__
