"""PRISM's operators and built-in functions over compiled nodes.

Each operator of :mod:`veribattery.lang.ops` combines its operands' nodes with the
numpy implementation of :mod:`.arrays`, folding constants; ``&``, ``|``, ``=>`` and
``? :`` evaluate a risky operand only on the rows that need it (see
:mod:`.expr`), and long chains are linked for :mod:`.chains`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, cast

import numpy as np

from veribattery._types import IntArray
from veribattery.errors import ModelError, PrismSemanticError, Span
from veribattery.explore.compile import arrays
from veribattery.explore.compile.chains import SPINE_LIMIT, Link, same_rows, unrolled
from veribattery.explore.compile.node import Fn, Node, constant_node
from veribattery.explore.compile.shape import size_at_least
from veribattery.lang import ops
from veribattery.lang.nodes import (
    Binary,
    Call,
    Unary,
)
from veribattery.lang.ops import OperatorError

__all__ = ["binary_node", "call_node", "ite_node", "lift", "unary_node"]


def lift(
    op: Callable[..., Any], args: Sequence[Node], risky: bool = False, link: Link | None = None
) -> Node:
    """Combine *args* with *op*, folding when every argument is a constant.

    :param link: how the value follows from one operand's (default: from the first)
    """
    if all(a.is_const for a in args):
        try:
            with np.errstate(all="ignore"):  # Java's doubles: inf - inf is NaN, silently
                return constant_node(op(*(a.const for a in args)))
        except ModelError as exc:  # ``N=0 ? 0 : mod(1, N)``: fails if ever evaluated
            return Node(fn=_failing(exc), risky=True)
    return _made(
        _applied(op, [a.fn for a in args]),
        link or _operand_link(op, args),
        risky=risky or any(a.risky for a in args),
        labels=any(a.labels for a in args),
        size=_size_of(args),
    )


def _failing(error: ModelError) -> Fn:
    """An operation of constants without a value: an error on any row (of the ones
    that fail, ``mod``, ``pow``, ``floor``..., every one gives ints)."""

    def evaluate(states: IntArray) -> Any:
        if states.shape[0]:
            raise error
        return np.empty(0, dtype=np.int64)

    return evaluate


def _operand_link(op: Callable[..., Any], args: Sequence[Node]) -> Link:
    """``op`` over *args* as a link through the first operand, or through the second
    when that one heads the longer chain (``a + (b + (c + ...))``)."""
    if len(args) == 2 and args[1].spine > args[0].spine:
        first = args[0].fn
        return Link(args[1], lambda states: (first(states), states), op)
    return Link(args[0], same_rows, _rest_applied(op, [a.fn for a in args[1:]]))


def _made(fn: Fn, link: Link, risky: bool, labels: bool, size: int) -> Node:
    """The node made by *link* (evaluated by *fn*, or in a loop deep down a chain)."""
    below = cast(Node, link.below)
    spine = below.spine + 1
    if spine >= SPINE_LIMIT:
        fn = unrolled(link)
    return Node(fn=fn, risky=risky, labels=labels, link=link, spine=spine, size=size)


#: :attr:`Node.size` stops growing here (shared sub-trees count once per use).
_SIZE_CAP = 1 << 30


def _size_of(operands: Sequence[Node]) -> int:
    """The size of an operation over *operands*."""
    return min(_SIZE_CAP, 1 + sum(operand.size for operand in operands))


def _applied(op: Callable[..., Any], fns: Sequence[Fn]) -> Fn:
    """``op`` over the evaluated arguments (unrolled for arity 1 and 2: it runs per layer)."""
    if len(fns) == 1:
        (f,) = fns
        return lambda states: op(f(states))
    if len(fns) == 2:
        f, g = fns
        return lambda states: op(f(states), g(states))
    return lambda states: op(*(h(states) for h in fns))


def _rest_applied(op: Callable[..., Any], rest: Sequence[Fn]) -> Callable[[Any, Any], Any]:
    """``op`` over the first argument's value and the others evaluated (a link's combine)."""
    if not rest:
        return lambda _states, value: op(value)
    if len(rest) == 1:
        (g,) = rest
        return lambda states, value: op(value, g(states))
    return lambda states, value: op(value, *(h(states) for h in rest))


def unary_node(expr: Unary, operand: Node) -> Node:
    return lift(arrays.UNARY[expr.op], [operand])


def binary_node(expr: Binary, left: Node, right: Node) -> Node:
    op = expr.op
    if ops.BINARY[op].lazy:
        return _logical(op, left, right, size_at_least(expr.right, _SKIP_SIZE))
    return lift(arrays.BINARY[op], [left, right])


#: A ``? :`` branch of at least this many operations per row is evaluated only on the
#: rows that pick it (:func:`ite_node`).
LARGE_BRANCH = 16

#: Right operands of ``&``/``|`` with at least this many nodes are skipped when the
#: left operand alone decides every row (see ``_skipping``).
_SKIP_SIZE = 4


def _logical(op: str, left: Node, right: Node, big: bool = False) -> Node:
    """``&``, ``|`` and ``=>``; a risky right operand is evaluated only where needed."""
    if op == "=>":
        left = lift(arrays.UNARY["!"], [left])
    combine = arrays.BINARY["&" if op == "&" else "|"]
    if left.is_const:  # PRISM short-circuits: ``false & pow(0, -1)=0`` is false
        if bool(left.const) == (op != "&"):
            return constant_node(np.bool_(op != "&"))
        return lift(combine, [left, right])
    if not right.subsettable:
        if big and not (left.is_const or right.is_const):
            return _skipping(combine, op != "&", left, right)
        return lift(combine, [left, right])
    # Rows where the left operand alone decides: false for ``&``, true for ``|``/``=>``.
    decided_value = op != "&"
    lfn, rfn = left.fn, right.fn

    def undecided(states: IntArray, value: Any) -> tuple[Any, Any]:
        first = np.broadcast_to(np.asarray(value, dtype=bool), (states.shape[0],))
        return first.copy(), first != decided_value

    def rest(states: IntArray, value: Any) -> Any:
        result, todo = undecided(states, value)
        if np.count_nonzero(todo):
            result[todo] = np.asarray(rfn(states[todo]), dtype=bool)
        return result

    def descend(states: IntArray) -> tuple[Any, IntArray | None]:
        result, todo = undecided(states, lfn(states))
        if np.count_nonzero(todo):
            return (result, todo), states[todo]
        return result, None

    def fill(kept: tuple[Any, Any], value: Any) -> Any:
        result, todo = kept
        result[todo] = np.asarray(value, dtype=bool)
        return result

    link = (Link(right, descend, fill) if right.spine > left.spine
            else Link(left, same_rows, rest))
    return _made(lambda states: rest(states, lfn(states)), link,
                 risky=True, labels=left.labels, size=_size_of((left, right)))


def _skipping(combine: Callable[..., Any], decided_value: bool, left: Node, right: Node) -> Node:
    """*combine* of the operands, the right one not evaluated when the left alone
    gives *decided_value* in every row: a guard ``s=3 & <a long battery condition>``
    costs one comparison in a BFS layer with no state at ``s=3``.
    """
    lfn, rfn = left.fn, right.fn

    def decided(first: Any) -> Any:
        """The left value as booleans, and whether it decides every row."""
        if type(first) is not np.ndarray or first.dtype != np.bool_:  # usually it is
            first = np.asarray(first, dtype=bool)
        # count_nonzero: a fraction of the cost of .any()/.all() on short arrays
        return first, first.ndim and np.count_nonzero(first) == (
            first.size if decided_value else 0)

    def rest(states: IntArray, value: Any) -> Any:
        first, done = decided(value)
        return first if done else combine(first, rfn(states))

    def descend(states: IntArray) -> tuple[Any, IntArray | None]:
        first, done = decided(lfn(states))
        return first, (None if done else states)

    link = (Link(right, descend, combine) if right.spine > left.spine
            else Link(left, same_rows, rest))
    return _made(lambda states: rest(states, lfn(states)), link,
                 risky=left.risky or right.risky, labels=left.labels or right.labels,
                 size=_size_of((left, right)))


def ite_node(cond: Node, then: Node, otherwise: Node) -> Node:
    """``cond ? then : otherwise``, linked through the branch that heads the longer
    chain (usually *otherwise*: ``c1 ? v1 : c2 ? v2 : ...``).

    Each branch is evaluated on the rows that pick it where one is risky or either is
    large (:data:`LARGE_BRANCH`); else both on every row (``np.where``), which costs
    less than splitting the rows for a few operations but evaluated the whole of a
    route's balanced ``k<=m ? (...) : (...)`` tree on every row.
    """
    if cond.is_const:
        chosen, other = (then, otherwise) if bool(cond.const) else (otherwise, then)
        if other.double and not chosen.double:  # an int branch of a double ``? :``
            return lift(_as_double, [chosen])
        return chosen
    large = (max(then.size, otherwise.size) >= LARGE_BRANCH
             and not (then.labels or otherwise.labels))
    if not (then.subsettable or otherwise.subsettable or large):
        return lift(np.where, [cond, then, otherwise], link=_both_link(cond, then, otherwise))
    cfn, tfn, ofn = cond.fn, then.fn, otherwise.fn

    def picked(states: IntArray) -> Any:
        return np.broadcast_to(np.asarray(cfn(states), dtype=bool), (states.shape[0],))

    def evaluate(states: IntArray) -> Any:
        pick = picked(states)
        return _merged(pick, tfn(states[pick]), ofn(states[~pick]))

    def to_then(states: IntArray) -> tuple[Any, IntArray | None]:
        pick = picked(states)
        return (pick, states), states[pick]

    def to_otherwise(states: IntArray) -> tuple[Any, IntArray | None]:
        pick = picked(states)
        return (pick, tfn(states[pick])), states[~pick]

    if then.spine > otherwise.spine:
        link = Link(then, to_then,
                    lambda kept, high: _merged(kept[0], high, ofn(kept[1][~kept[0]])))
    else:
        link = Link(otherwise, to_otherwise, lambda kept, low: _merged(kept[0], kept[1], low))
    return _made(evaluate, link, risky=cond.risky or then.risky or otherwise.risky,
                 labels=cond.labels, size=_size_of((cond, then, otherwise)))


def _both_link(cond: Node, then: Node, otherwise: Node) -> Link:
    """``np.where(cond, then, otherwise)``, all three on every row, as a link through
    the branch that heads the longer chain."""
    cfn, tfn, ofn = cond.fn, then.fn, otherwise.fn
    if then.spine > otherwise.spine:
        return Link(then, lambda states: ((cfn(states), states), states),
                    lambda kept, high: np.where(kept[0], high, ofn(kept[1])))
    return Link(otherwise, lambda states: ((cfn(states), tfn(states)), states),
                lambda kept, low: np.where(kept[0], kept[1], low))


def _merged(pick: Any, high: Any, low: Any) -> Any:
    """*high* where *pick*, *low* elsewhere, in the type that holds both."""
    out = np.empty(pick.shape[0], dtype=np.result_type(high, low))
    out[pick] = high
    out[~pick] = low
    return out


def _as_double(x: Any) -> Any:
    return np.asarray(x, dtype=np.float64)[()]


# ---------------------------------------------------------------------------
# Built-in functions
# ---------------------------------------------------------------------------


def call_node(expr: Call, args: list[Node]) -> Node:
    func, span = expr.func, expr.span
    function = ops.FUNCTIONS.get(func)
    if function is None or not function.accepts(len(args)):
        raise PrismSemanticError(f"wrong number of arguments to {func}", span)
    apply = arrays.FUNCTIONS[func]
    if not function.may_fail:
        return lift(apply, args)
    # (ops' types: a variable, int or bool, counts as an int: bools take no numbers)
    fails = function.fails(["double" if a.double else "int" for a in args])
    return lift(_located(apply, span), args, risky=fails)


def _located(apply: Callable[..., Any], span: Span) -> Callable[..., Any]:
    """*apply*, its errors reported at *span*."""

    def located(*args: Any) -> Any:
        try:
            return apply(*args)
        except OperatorError as exc:
            raise ModelError(str(exc), span) from None

    return located
