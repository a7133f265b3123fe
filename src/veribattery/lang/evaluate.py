"""Evaluation of closed expressions with PRISM's semantics (constants, bounds, folding).

The operators are those of :mod:`veribattery.lang.ops` on Python scalars: ints stay
exact Python ints, doubles are floats, and ``&``, ``|``, ``=>`` and ``? :``
evaluate an operand only when PRISM does.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
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
    ValueType,
)
from veribattery.lang.ops import BINARY, FUNCTIONS, UNARY, OperatorError, decided_by
from veribattery.lang.typecheck import TypeEnv, type_of


class EvaluationError(PrismSemanticError):
    """An expression has no value: not constant, or an arithmetic error."""


def evaluate(expr: Expr, values: Mapping[str, Value]) -> Value:
    """The value of *expr*, whose identifiers must all be in *values*.

    ``&``, ``|`` and ``=>`` short-circuit, so ``x!=0 & 1/x>2`` never divides by zero,
    and ``? :`` evaluates only the branch it takes (its value is a double if the
    other branch is one). The evaluation keeps its own stack: a constant may be a
    sum of thousands of terms.

    :raises EvaluationError: for an unknown name or an operator without a value
    """
    run = _Evaluation(values)
    todo: list[tuple[int, Expr]] = [(_EVALUATE, expr)]
    while todo:
        step, node = todo.pop()
        if step == _EVALUATE:
            run.start(node, todo)
        else:
            _STEPS[step](run, cast(Any, node), todo)
    return run.results[0]


# What is left to do for a node once some of its operands are on the results stack.
_EVALUATE, _NEGATE, _LEFT_DONE, _APPLY, _TRUTH, _CHOOSE, _CHOSEN, _CALL = range(8)


class _Evaluation:
    """The values of the identifiers and the stack of results of one evaluation."""

    def __init__(self, values: Mapping[str, Value]) -> None:
        self.values = values
        self.results: list[Value] = []
        self._types: TypeEnv | None = None

    def start(self, node: Expr, todo: list[tuple[int, Expr]]) -> None:
        """Push *node*'s value, or the steps that compute it."""
        if isinstance(node, IntLit | DoubleLit | BoolLit):
            self.results.append(node.value)
        elif isinstance(node, Ident):
            if node.name not in self.values:
                raise EvaluationError(f"'{node.name}' is not a constant", node.span)
            self.results.append(self.values[node.name])
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

    def is_double(self, expr: Expr) -> bool:
        """Whether *expr* has type double (False where its type is unknown)."""
        if self._types is None:
            self._types = TypeEnv(_ValueTypes(self.values), memo=True)
        try:
            return type_of(expr, self._types) == "double"
        except PrismSemanticError:
            return False


class _ValueTypes(Mapping[str, ValueType]):
    """The types of the values of a mapping, looked up as needed."""

    def __init__(self, values: Mapping[str, Value]) -> None:
        self.known = values

    def __getitem__(self, name: str) -> ValueType:
        value = self.known[name]
        if isinstance(value, bool):
            return "bool"
        return "int" if isinstance(value, int) else "double"

    def __iter__(self) -> Iterator[str]:
        return iter(self.known)

    def __len__(self) -> int:
        return len(self.known)


def _negate(run: _Evaluation, node: Unary, todo: list[tuple[int, Expr]]) -> None:
    run.results.append(UNARY[node.op].apply(run.results.pop()))


def _left_done(run: _Evaluation, node: Binary, todo: list[tuple[int, Expr]]) -> None:
    """The left operand is known: decide ``&``/``|``/``=>`` by it, or evaluate the right one."""
    op = node.op
    if BINARY[op].lazy:
        decided = decided_by(op, bool(run.results.pop()))
        if decided is not None:
            run.results.append(decided)
            return
        todo += [(_TRUTH, node), (_EVALUATE, node.right)]
        return
    todo += [(_APPLY, node), (_EVALUATE, node.right)]


def _apply(run: _Evaluation, node: Binary, todo: list[tuple[int, Expr]]) -> None:
    right = run.results.pop()
    try:
        run.results.append(BINARY[node.op].apply(run.results.pop(), right))
    except OperatorError as exc:
        raise EvaluationError(f"cannot evaluate '{node.op}': {exc}", node.span) from None


def _truth(run: _Evaluation, node: Expr, todo: list[tuple[int, Expr]]) -> None:
    run.results.append(bool(run.results.pop()))


def _choose(run: _Evaluation, node: Ite, todo: list[tuple[int, Expr]]) -> None:
    todo += [(_CHOSEN, node), (_EVALUATE, node.then if run.results.pop() else node.otherwise)]


def _chosen(run: _Evaluation, node: Ite, todo: list[tuple[int, Expr]]) -> None:
    """An int branch of a ``? :`` whose other branch is a double gives a double."""
    value = run.results[-1]
    if type(value) is int and (run.is_double(node.then) or run.is_double(node.otherwise)):
        run.results[-1] = float(value)


def _call_step(run: _Evaluation, node: Call, todo: list[tuple[int, Expr]]) -> None:
    results = run.results
    count = len(node.args)
    args = results[len(results) - count :]
    del results[len(results) - count :]
    results.append(_call(node, args))


_STEPS: dict[int, Callable[[_Evaluation, Any, list[tuple[int, Expr]]], None]] = {
    _NEGATE: _negate,
    _LEFT_DONE: _left_done,
    _APPLY: _apply,
    _TRUTH: _truth,
    _CHOOSE: _choose,
    _CHOSEN: _chosen,
    _CALL: _call_step,
}


def _call(expr: Call, args: Sequence[Value]) -> Value:
    function = FUNCTIONS.get(expr.func)
    if function is None or not function.accepts(len(args)):
        raise EvaluationError(f"wrong number of arguments to {expr.func}", expr.span)
    try:
        return function.apply(*args)
    except OperatorError as exc:
        raise EvaluationError(f"cannot evaluate {expr.func}(...): {exc}", expr.span) from None
