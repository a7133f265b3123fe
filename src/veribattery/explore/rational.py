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

import math
from collections.abc import Callable, Collection, Mapping, Sequence
from fractions import Fraction
from typing import Any, TypeAlias

import numpy as np
from gmpy2 import mpq

from veribattery._types import IntArray
from veribattery.errors import ModelError, PrismSemanticError, Span
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    ConstDecl,
    DoubleLit,
    Expr,
    Ident,
    IntLit,
    Ite,
    Unary,
    Value,
)

__all__ = [
    "ExactScalar",
    "ObjectArray",
    "evaluate_rational",
    "exact_constants",
    "rational",
    "tabulate",
]

ObjectArray: TypeAlias = np.ndarray
#: An exact constant: a rational (ints included) or a boolean.
ExactScalar: TypeAlias = mpq | bool

_ZERO = mpq(0)


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
# Constants
# ---------------------------------------------------------------------------


def exact_constants(
    decls: Sequence[ConstDecl],
    given: Mapping[str, Value | str],
    outer: Mapping[str, ExactScalar] | None = None,
) -> dict[str, ExactScalar]:
    """Exact values of *decls* (defined ones evaluated rationally, undefined from *given*).

    The flattening (:func:`~veribattery.lang.flatten_model`) has already
    checked names, types and cycles; this only recomputes the values without
    rounding: ``const double p = 1/3`` is 1/3, ``--const p=0.7`` is 7/10.
    """
    values: dict[str, ExactScalar] = dict(outer or {})
    pending = {d.name: d for d in decls}
    uses = {d.name: _constants_used(d, pending) for d in decls}
    defined = _defined(uses, pending, given)
    for decl in decls:
        if defined[decl.name]:
            for name in _dependencies_first(decl.name, uses, values.keys()):
                values[name] = _constant(pending[name], given, values)
    return values


def _constants_used(decl: ConstDecl, pending: Mapping[str, ConstDecl]) -> list[str]:
    """The constants of *pending* that *decl* is defined with, in order of appearance."""
    if decl.value is None:
        return []
    return [n.name for n in walk(decl.value) if isinstance(n, Ident) and n.name in pending]


def _dependencies_first(
    name: str, uses: Mapping[str, list[str]], known: Collection[str]
) -> list[str]:
    """*name* and the constants it needs that are not *known*, each after those it
    uses (depth first, in order of appearance; a stack of its own: chains are long)."""
    order: list[str] = []
    placed = set(known)
    todo: list[tuple[str, bool]] = [(name, False)]
    while todo:
        current, ready = todo.pop()
        if ready:
            order.append(current)
        elif current not in placed:
            placed.add(current)  # flattening rejected cycles: each name is entered once
            todo.append((current, True))
            todo.extend((n, False) for n in reversed(uses[current]))
    return order


def _defined(
    uses: Mapping[str, list[str]], pending: Mapping[str, ConstDecl], given: Mapping[str, object]
) -> dict[str, bool]:
    """Per constant, whether it has a value: given, or defined from constants that
    all have one.

    A properties file may declare a constant it never uses and nobody gives
    (``const int x; // unused``); the float path accepts that, and so must this one.
    """
    defined: dict[str, bool] = {}
    for name in pending:
        todo: list[tuple[str, bool]] = [(name, False)]
        while todo:
            current, ready = todo.pop()
            if ready:
                own = pending[current].value is not None or current in given
                defined[current] = own and all(defined.get(n, False) for n in uses[current])
            elif current not in defined:
                defined[current] = False  # until known (and so for a cycle)
                todo.append((current, True))
                todo.extend((n, False) for n in reversed(uses[current]))
    return defined


def _constant(
    decl: ConstDecl, given: Mapping[str, Value | str], values: Mapping[str, ExactScalar]
) -> ExactScalar:
    if decl.value is None:
        raw = given[decl.name]
        if decl.type == "bool":
            return raw in (True, "true")
        return rational(raw.strip() if isinstance(raw, str) else raw)
    result = evaluate_rational(decl.value, values, {}, 1)[0]
    return bool(result) if decl.type == "bool" else result


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
    return _as_objects([mpq(int(v)) for v in values])


def _as_objects(items: Sequence[Any]) -> ObjectArray:
    array = np.empty(len(items), dtype=object)
    array[:] = items
    return array


# ---------------------------------------------------------------------------
# The evaluator
# ---------------------------------------------------------------------------


def evaluate_rational(
    expr: Expr,
    constants: Mapping[str, ExactScalar],
    variables: Mapping[str, np.ndarray],
    n: int,
) -> np.ndarray:
    """*expr* evaluated exactly for *n* valuations (object array of mpq, or bools).

    :param constants: exact constant values (scalars).
    :param variables: per variable, an array of *n* values (mpq objects or bools).
    :raises ModelError: for an operation without an exact rational result.
    """
    return _Evaluator(constants, variables, n).run(expr)


class _Evaluator:
    """One evaluation: constants are broadcast, sub-expressions see row subsets.

    It keeps its own stack of steps (each with the evaluator of its rows) and of
    values: an expression may be a chain of thousands of operators.
    """

    def __init__(
        self, constants: Mapping[str, ExactScalar], variables: Mapping[str, np.ndarray], n: int
    ) -> None:
        self.constants = constants
        self.variables = variables
        self.n = n

    def subset(self, mask: np.ndarray) -> _Evaluator:
        chosen = {k: v[mask] for k, v in self.variables.items()}
        return _Evaluator(self.constants, chosen, int(np.count_nonzero(mask)))

    def full(self, value: Any) -> np.ndarray:
        if isinstance(value, bool | np.bool_):
            return np.full(self.n, bool(value), dtype=bool)
        return np.full(self.n, value, dtype=object)

    def run(self, expr: Expr) -> np.ndarray:
        values: list[np.ndarray] = []
        todo: list[_Step] = [(_EVALUATE, expr, self)]
        while todo:
            step, node, context = todo.pop()
            if step == _EVALUATE:
                context.start(node, values, todo)
            else:
                _STEPS[step](node, context, values, todo)
        return values[0]

    def start(self, expr: Expr, values: list[np.ndarray], todo: list[_Step]) -> None:
        """Push the value of *expr* on these rows, or the steps that compute it."""
        if isinstance(expr, IntLit):
            values.append(self.full(mpq(expr.value)))
        elif isinstance(expr, DoubleLit):
            values.append(self.full(rational(expr.text) if expr.text else rational(expr.value)))
        elif isinstance(expr, BoolLit):
            values.append(self.full(expr.value))
        elif isinstance(expr, Ident):
            values.append(self._ident(expr))
        elif isinstance(expr, Unary):
            todo += [(_NEGATE, expr, self), (_EVALUATE, expr.operand, self)]
        elif isinstance(expr, Binary) and expr.op in ("&", "|", "=>"):
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

    def _ident(self, expr: Ident) -> np.ndarray:
        if expr.name in self.variables:
            return self.variables[expr.name]
        if expr.name in self.constants:
            return self.full(self.constants[expr.name])
        raise PrismSemanticError(f"unknown identifier '{expr.name}'", expr.span)


#: A step of :meth:`_Evaluator.run`: what to do, for which node, with what (the
#: evaluator of the rows, or what an operator kept between its operands).
_Step = tuple[int, Any, Any]
_EVALUATE, _NEGATE, _APPLY, _LEFT_DONE, _RIGHT_DONE, _CHOOSE, _BRANCHES_DONE, _CALL = range(8)


def _negate(expr: Unary, rows: _Evaluator, values: list[np.ndarray], todo: list[_Step]) -> None:
    operand = values.pop()
    values.append(~_bools(operand) if expr.op == "!" else -operand)


def _apply(expr: Binary, rows: _Evaluator, values: list[np.ndarray], todo: list[_Step]) -> None:
    right = values.pop()
    left = values.pop()
    if expr.op == "/":
        values.append(_divide(left, right, expr.span))
    elif expr.op == "<=>":
        values.append(np.asarray(_bools(left) == _bools(right)))
    else:
        result = _OPERATORS[expr.op](left, right)
        values.append(np.asarray(result, dtype=bool) if expr.op in _RELATIONS else result)


def _left_done(expr: Binary, rows: _Evaluator, values: list[np.ndarray], todo: list[_Step]) -> None:
    """``&``, ``|``, ``=>``: the right operand only where the left does not decide."""
    left = _bools(values.pop())
    if expr.op == "=>":
        left = ~left
    decided = left if expr.op != "&" else ~left
    result = left.copy()
    undecided = ~decided
    if undecided.any():
        todo += [(_RIGHT_DONE, expr, (result, undecided)),
                 (_EVALUATE, expr.right, rows.subset(undecided))]
    else:
        values.append(result)


def _right_done(
    expr: Binary, kept: tuple[np.ndarray, np.ndarray], values: list[np.ndarray],
    todo: list[_Step],
) -> None:
    result, undecided = kept
    result[undecided] = _bools(values.pop())
    values.append(result)


def _choose(expr: Ite, rows: _Evaluator, values: list[np.ndarray], todo: list[_Step]) -> None:
    pick = _bools(values.pop())
    todo += [(_BRANCHES_DONE, expr, (rows, pick)),
             (_EVALUATE, expr.otherwise, rows.subset(~pick)),
             (_EVALUATE, expr.then, rows.subset(pick))]


def _branches_done(
    expr: Ite, kept: tuple[_Evaluator, np.ndarray], values: list[np.ndarray], todo: list[_Step]
) -> None:
    rows, pick = kept
    low = values.pop()
    high = values.pop()
    kind = bool if high.dtype == bool and low.dtype == bool else object
    out = np.empty(rows.n, dtype=kind)
    out[pick] = high
    out[~pick] = low
    values.append(out)


def _call_step(expr: Call, rows: _Evaluator, values: list[np.ndarray], todo: list[_Step]) -> None:
    count = len(expr.args)
    args = values[len(values) - count :]
    del values[len(values) - count :]
    values.append(_call(expr, args))


_STEPS: dict[int, Callable[[Any, Any, list[np.ndarray], list[_Step]], None]] = {
    _NEGATE: _negate,
    _APPLY: _apply,
    _LEFT_DONE: _left_done,
    _RIGHT_DONE: _right_done,
    _CHOOSE: _choose,
    _BRANCHES_DONE: _branches_done,
    _CALL: _call_step,
}


def _bools(values: np.ndarray) -> np.ndarray:
    if values.dtype == bool:
        return values
    return np.asarray(values != _ZERO, dtype=bool)  # a 0/1 int used as a condition


_RELATIONS = frozenset({"=", "!=", "<", "<=", ">", ">="})

_OPERATORS: dict[str, Callable[[Any, Any], Any]] = {
    "+": np.add,
    "-": np.subtract,
    "*": np.multiply,
    "=": np.equal,
    "!=": np.not_equal,
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
}


def _divide(left: np.ndarray, right: np.ndarray, span: Span) -> np.ndarray:
    if np.any(right == _ZERO):
        raise ModelError("division by zero (no exact rational value)", span)
    return np.asarray(left / right, dtype=object)


# ---------------------------------------------------------------------------
# Built-in functions
# ---------------------------------------------------------------------------


def _call(expr: Call, args: list[np.ndarray]) -> np.ndarray:
    func = expr.func
    if func in ("min", "max"):
        pick = np.minimum if func == "min" else np.maximum
        result = args[0]
        for arg in args[1:]:
            result = pick(result, arg)
        return np.asarray(result, dtype=object)
    if func in ("floor", "ceil"):
        round_ = _floor if func == "floor" else _ceil
        return _as_objects([round_(x) for x in args[0]])
    if func == "pow":
        return _power(args[0], args[1], expr)
    if func == "mod":
        return _modulo(args[0], args[1], expr)
    raise ModelError(
        f"{_text(expr)}: {func} has no exact rational value; --exact needs rational "
        "expressions (+ - * / min max floor ceil mod, pow with an integer exponent)",
        expr.span,
    )


def _floor(x: mpq) -> mpq:
    return mpq(math.floor(x))


def _ceil(x: mpq) -> mpq:
    return mpq(math.ceil(x))


def _power(base: np.ndarray, exponent: np.ndarray, expr: Call) -> np.ndarray:
    if any(e.denominator != 1 for e in exponent):
        raise ModelError(
            f"{_text(expr)}: pow with a non-integer exponent has no exact rational value",
            expr.span,
        )
    out = []
    for b, e in zip(base, exponent, strict=True):
        if b == _ZERO and e.numerator < 0:
            raise ModelError(f"{_text(expr)}: zero to a negative power", expr.span)
        out.append(b ** int(e.numerator))
    return _as_objects(out)


def _modulo(a: np.ndarray, b: np.ndarray, expr: Call) -> np.ndarray:
    if any(x.denominator != 1 for x in a) or any(y.denominator != 1 for y in b):
        raise ModelError(f"{_text(expr)}: mod requires integer arguments", expr.span)
    if any(y.numerator <= 0 for y in b):
        raise ModelError(f"{_text(expr)}: modulo with non-positive divisor", expr.span)
    pairs = zip(a, b, strict=True)
    return _as_objects([mpq(int(x.numerator) % int(y.numerator)) for x, y in pairs])


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
