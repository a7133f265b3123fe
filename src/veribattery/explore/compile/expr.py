"""Compile PRISM expressions into numpy functions over many states at once.

A compiled expression takes an ``(n, n_vars)`` int64 array of variable values
(one row per state) and returns an array of length *n*. Integer arithmetic stays
int64 and exact; ``/`` always gives a float, as in PRISM. Boolean variables are
stored as 0/1, which numpy's logical functions and comparisons treat correctly.

The operators are those of :mod:`veribattery.lang.ops`, in the numpy domain of
:mod:`.arrays` (``x/0`` is infinite, as in PRISM). Sub-expressions whose operands
are all literals are folded at compile time. Operations that have no value for some
operands (``mod``, ``pow`` of ints, ``floor``/``ceil``/``round`` of doubles) are
*risky*: the branches of ``? :`` and the right operands of ``&``, ``|`` and ``=>``
that contain them are evaluated only on the rows that need them, as PRISM evaluates
them, so that ``c=0 | pow(2, c-1)>0`` reports no negative exponent where ``c=0``.

Nothing here recurses over an expression: compiling keeps its own stack, and the
closures of a long chain (thousands of terms) run in a loop (:mod:`.chains`).
"""

from __future__ import annotations

import dataclasses
import weakref
from collections.abc import Mapping, Sequence
from typing import Any, cast

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.errors import ModelError, PrismSemanticError
from veribattery.explore.compile.node import (
    CompileCache,
    CompiledExpr,
    Fn,
    Node,
    Scope,
    constant_node,
    memoised,
)
from veribattery.explore.compile.operators import binary_node, call_node, ite_node, unary_node
from veribattery.explore.compile.shape import cached_shape, sub_expressions
from veribattery.explore.compile.tables import (
    table_lookup,
    valuation_grid,
    worth_tabulating,
)
from veribattery.lang import ops
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    DoubleLit,
    Expr,
    Ident,
    IntLit,
    Ite,
    LabelRef,
    Unary,
    ValueType,
)

__all__ = [
    "CompileCache",
    "CompiledExpr",
    "compile_expr",
    "constant_value",
    "may_fail",
    "variables_of",
]


def compile_expr(
    expr: Expr,
    variable_names: Sequence[str],
    label_masks: Mapping[str, BoolArray] | None = None,
    ranges: Mapping[str, tuple[int, int]] | None = None,
    cache: CompileCache | None = None,
) -> CompiledExpr:
    """Compile *expr* into a function over an ``(n, n_vars)`` array of variable values.

    The result always has length *n* (constants are broadcast). It may share memory
    with the input (a bare variable returns its column): do not write to it.

    :param expr: an expression using only variables, literals, operators and
        built-in functions (and ``"label"`` references if *label_masks* is given).
    :param variable_names: the column names of the state arrays, in order.
    :param label_masks: label name to mask, aligned with the rows evaluated.
    :param ranges: the variables' bounds; when given, sub-expressions whose variables
        span at most ``TABLE_LIMIT`` valuations are evaluated once into a lookup table.
    :param cache: compiled nodes (tables included) shared between compilations; their
        results are remembered per input array (see :class:`CompileCache`).
    :raises PrismSemanticError: for an unknown identifier or label.
    """
    columns = {name: i for i, name in enumerate(variable_names)}
    node = _compile(expr, Scope(columns, label_masks, ranges, cache))

    fn = _quiet(node.fn) if node.noisy else node.fn

    def evaluate(states: IntArray) -> np.ndarray:
        value = fn(states)
        if type(value) is np.ndarray and value.ndim:  # the common case, checked cheaply
            return value
        value = np.asarray(value)
        if value.ndim == 0:
            return np.full(states.shape[0], value, dtype=value.dtype)
        return value

    if node.risky or node.labels:
        _MAY_FAIL.add(evaluate)
    return evaluate


def _quiet(fn: Fn) -> Fn:
    """*fn* without numpy's warnings: infinities and NaN are values here (``x/0``)."""

    def evaluate(states: IntArray) -> Any:
        with np.errstate(all="ignore"):
            return fn(states)

    return evaluate


#: The compiled expressions that may raise on some rows or read label masks.
_MAY_FAIL: weakref.WeakSet[CompiledExpr] = weakref.WeakSet()


def may_fail(fn: CompiledExpr) -> bool:
    """Whether the compiled expression *fn* may raise on some rows of a variables'
    domain (division, ``mod``, ``pow`` outside a lookup table) or reads label masks
    (which are aligned with the rows it was compiled for): such an expression must
    be evaluated on exactly the rows that need it. An expression whose risky parts
    were all tabulated without error cannot fail on a state within the ranges.
    """
    return fn in _MAY_FAIL


def variables_of(expr: Expr, cache: CompileCache | None = None) -> set[str]:
    """The identifiers that occur in *expr*; with *cache*, each structurally distinct
    sub-expression is walked once across calls (a route's formulas recur in every
    guard that reads them: 5.6 s of a 100 x 100 farm's build walked them afresh)."""
    return set(cached_shape(expr, cache)[0])


# ---------------------------------------------------------------------------
# Leaves
# ---------------------------------------------------------------------------


def _compile(expr: Expr, scope: Scope) -> Node:
    """The compiled node of *expr*: operands first, each sub-expression once (per
    cache), on an explicit stack, in the order a recursive compiler would go."""
    done: dict[int, Node] = {}
    stack: list[tuple[Expr, bool]] = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        if ready:
            done[id(node)] = _finished(node, [done[id(c)] for c in sub_expressions(node)], scope)
            continue
        if id(node) in done:
            continue
        found = _cached(node, scope)
        if found is not None:
            done[id(node)] = found
            continue
        table = _tabulated(node, scope)
        if table is not None:
            done[id(node)] = _stored(node, table, scope)
            continue
        operands = _operands(node)
        if not operands:
            done[id(node)] = _finished(node, [], scope)
            continue
        stack.append((node, True))
        stack.extend([(operand, False) for operand in reversed(operands)])
    return done[id(expr)]


def _store(scope: Scope) -> dict[int, Node] | None:
    cache = scope.cache
    if cache is None:
        return None
    return cache.nodes if scope.ranges is not None else cache.plain


def _cached(expr: Expr, scope: Scope) -> Node | None:
    """The node compiled before for an expression equal to *expr*, if any."""
    store = _store(scope)
    if store is None or scope.cache is None:
        return None
    return store.get(scope.cache.key(expr))


def _operands(expr: Expr) -> tuple[Expr, ...]:
    """The operands to compile before *expr*; an error for what is no state expression."""
    if isinstance(expr, IntLit | DoubleLit | BoolLit | Ident | LabelRef):
        return ()
    if isinstance(expr, Unary | Binary | Ite | Call):
        return sub_expressions(expr)
    raise PrismSemanticError(
        f"{type(expr).__name__} is not allowed in a state expression", expr.span
    )


def _finished(expr: Expr, operands: list[Node], scope: Scope) -> Node:
    """The node of *expr* from its compiled operands, stored."""
    return _stored(expr, _compile_node(expr, operands, scope), scope)


def _stored(expr: Expr, node: Node, scope: Scope) -> Node:
    """*node*, the compiled *expr*, memoised where the cache asks it and stored."""
    cache = scope.cache
    store = _store(scope)
    if cache is not None and store is not None:
        if (scope.ranges is not None and cache.memoise
                and not (node.is_const or isinstance(expr, Ident | LabelRef))):
            node = dataclasses.replace(node, fn=memoised(node.fn))
        store[cache.key(expr)] = node
    return node


def _compile_node(expr: Expr, operands: list[Node], scope: Scope) -> Node:
    """The node of *expr* made from its compiled *operands* (a leaf has none), with
    its type and whether it may see infinities."""
    node = _built(expr, operands, scope)
    double = _is_double(expr, operands, node)
    noisy = _own_noise(expr, operands, node, double) or any(o.noisy for o in operands)
    if node.double == double and node.noisy == noisy:
        return node
    return dataclasses.replace(node, double=double, noisy=noisy)


def _is_double(expr: Expr, operands: list[Node], node: Node) -> bool:
    """Whether *node* has PRISM type double (by :mod:`~veribattery.lang.ops`'s rules)."""
    if node.is_const:
        return bool(np.asarray(node.const).dtype.kind == "f")
    kinds: list[ValueType] = ["double" if o.double else "int" for o in operands]
    if isinstance(expr, Unary):
        return ops.UNARY[expr.op].result(kinds) == "double"
    if isinstance(expr, Binary):
        return ops.BINARY[expr.op].result(kinds) == "double"
    if isinstance(expr, Ite):
        return operands[1].double or operands[2].double
    if isinstance(expr, Call):
        return ops.FUNCTIONS[expr.func].result(kinds) == "double"
    return False


def _own_noise(expr: Expr, operands: list[Node], node: Node, double: bool) -> bool:
    """Whether *node* may make an infinity or a NaN of finite operands (or is one)."""
    if node.is_const:
        return not bool(np.all(np.isfinite(node.const)))
    if isinstance(expr, Binary) and expr.op == "/":
        divisor = operands[1]
        return not (divisor.is_const and bool(np.all(np.isfinite(divisor.const)))
                    and bool(np.all(divisor.const != 0)))
    if isinstance(expr, Call):
        return expr.func == "log" or (expr.func == "pow" and double)
    return False


def _built(expr: Expr, operands: list[Node], scope: Scope) -> Node:
    """The node of *expr* made from its compiled *operands*."""
    if isinstance(expr, IntLit):
        return constant_node(_int64(expr))
    if isinstance(expr, DoubleLit):
        return constant_node(np.float64(expr.value))
    if isinstance(expr, BoolLit):
        return constant_node(np.bool_(expr.value))
    if isinstance(expr, Ident):
        return _variable(expr, scope.columns)
    if isinstance(expr, LabelRef):
        return _label(expr, scope.labels)
    if isinstance(expr, Unary):
        return unary_node(expr, operands[0])
    if isinstance(expr, Binary):
        return binary_node(expr, operands[0], operands[1])
    if isinstance(expr, Ite):
        return ite_node(operands[0], operands[1], operands[2])
    return call_node(cast(Call, expr), operands)


def _int64(expr: IntLit) -> np.int64:
    """An int literal (also a substituted constant or a folded sub-expression) as the
    64-bit int the engine computes in."""
    if not ops.INT_MIN <= expr.value <= ops.INT_MAX:
        raise PrismSemanticError(ops.out_of_int_range(expr.value), expr.span)
    return np.int64(expr.value)


def _variable(expr: Ident, columns: Mapping[str, int]) -> Node:
    if expr.name not in columns:
        raise PrismSemanticError(f"unknown identifier '{expr.name}'", expr.span)
    column = columns[expr.name]
    return Node(fn=lambda states: states[:, column])


def _label(expr: LabelRef, labels: Mapping[str, BoolArray] | None) -> Node:
    if labels is None or expr.name not in labels:
        raise PrismSemanticError(f'unknown label "{expr.name}"', expr.span)
    mask = labels[expr.name]
    return Node(fn=lambda _states: mask, labels=True)


def _tabulated(expr: Expr, scope: Scope) -> Node | None:
    """*expr* as a lookup table over its variables' domain, or None: not worth it (or no
    ranges), or it fails on some valuation (e.g. ``mod(x, y)`` at ``y=0``), where it is
    compiled row-wise and its operands get their own chance.

    The table is made top-down, from *expr* compiled row-wise: its sub-expressions over
    the same small domain are not tabulated on their own. Made bottom-up, each level of a
    conditional over a route held a table over the whole route (a 250 x 250 farm's
    formulas took 9 GB), and the tables were dropped once their parent's was made.
    """
    if scope.ranges is None or not worth_tabulating(expr, scope.ranges, scope.cache):
        return None
    direct = _compile(expr, dataclasses.replace(scope, ranges=None))
    names = sorted(cached_shape(expr, scope.cache)[0], key=lambda n: scope.columns[n])
    lows = [scope.ranges[n][0] for n in names]
    shape = [scope.ranges[n][1] - low + 1 for n, low in zip(names, lows, strict=True)]
    cols = [scope.columns[n] for n in names]
    grid = valuation_grid(cols, lows, shape, len(scope.columns), scope.cache)
    try:
        with np.errstate(all="ignore"):  # x/y at y=0: infinite, a value as any other
            table = np.broadcast_to(np.asarray(direct.fn(grid)), grid.shape[:1]).copy()
    except ModelError:
        return None
    noisy = table.dtype.kind == "f" and not bool(np.isfinite(table).all())
    return Node(fn=table_lookup(table, cols, lows, shape, scope.cache), double=direct.double,
                 noisy=noisy)


# ---------------------------------------------------------------------------
# Static facts used to skip run-time checks
# ---------------------------------------------------------------------------


def constant_value(
    expr: Expr, variable_names: Sequence[str], cache: CompileCache | None = None
) -> Any | None:
    """The value of *expr* if it folds to a constant, else None.

    :param cache: compiled nodes to reuse (see :class:`CompileCache`).
    """
    columns = {name: i for i, name in enumerate(variable_names)}
    node = _compile(expr, Scope(columns, cache=cache))
    return node.const.item() if node.is_const else None
