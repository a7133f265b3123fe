"""Compile PRISM expressions into numpy functions over many states at once.

A compiled expression takes an ``(n, n_vars)`` int64 array of variable values
(one row per state) and returns an array of length *n*. Integer arithmetic stays
int64 and exact; ``/`` always gives a float, as in PRISM. Boolean variables are
stored as 0/1, which numpy's logical functions and comparisons treat correctly.

Sub-expressions whose operands are all literals are folded at compile time.
Operations that can fail on some rows (division, ``mod``, ``pow``) are *risky*:
the branches of ``? :`` and the right operands of ``&``, ``|`` and ``=>`` that
contain them are evaluated only on the rows that need them, so that a guard such
as ``y>0 & x/y>1`` does not report a division by zero where ``y=0``.

Nothing here recurses over an expression: compiling keeps its own stack, and the
closures of a long chain (thousands of terms) run in a loop (:mod:`.chains`).
"""

from __future__ import annotations

import dataclasses
import math
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.errors import ModelError, PrismSemanticError, Span
from veribattery.explore.chains import SPINE_LIMIT, Link, same_rows, unrolled
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
)

__all__ = [
    "CompileCache",
    "CompiledExpr",
    "compile_expr",
    "constant_value",
    "may_fail",
    "variables_of",
]

#: The public shape of a compiled expression.
CompiledExpr = Callable[[IntArray], np.ndarray]
# Internal evaluators may return a numpy scalar where the value is constant.
_Fn = Callable[[IntArray], Any]


@dataclass(frozen=True, slots=True)
class _Node:
    """A compiled sub-expression: an evaluator, or a folded constant."""

    fn: _Fn
    const: Any = None
    is_const: bool = False
    risky: bool = False  # may raise on some rows
    labels: bool = False  # reads label masks (aligned with all rows: no row subsets)
    link: Link | None = None  # how the value follows from its deepest operand's
    spine: int = 0  # links in a row down from here: evaluated in a loop from SPINE_LIMIT
    plain: _Fn | None = None  # *fn* without its memo (tables are made with it)

    @property
    def subsettable(self) -> bool:
        """Whether evaluating this node on a subset of rows is both useful and safe."""
        return self.risky and not self.labels


@dataclass(frozen=True, slots=True)
class _Scope:
    """What compilation needs besides the expression.

    With *ranges* (variable name → (low, high)), sub-expressions over a small
    domain are tabulated once; *cache* shares compiled nodes across compilations.
    """

    columns: Mapping[str, int]
    labels: Mapping[str, BoolArray] | None = None
    ranges: Mapping[str, tuple[int, int]] | None = None
    cache: CompileCache | None = None


class CompileCache:
    """Compiled sub-expressions shared by all the expressions of one program.

    Every distinct sub-expression is compiled once (common subexpressions of
    guards and updates become one node, tables included), and each node
    remembers its results for the last two state arrays it was applied to, by
    identity: the explorer evaluates every guard of a BFS layer on the same
    frontier array, so a formula shared by a dozen guards (a cost, a voltage
    level) is computed once per layer. Arrays passed to compiled expressions
    must therefore not be modified in place afterwards.

    :param memoise: remember results per input array; False shares only the
        compiled nodes and tables (no array is kept alive by the cache).
    """

    def __init__(self, memoise: bool = True) -> None:
        self.memoise = memoise
        self.nodes: dict[int, _Node] = {}
        self.plain: dict[int, _Node] = {}  # row-wise nodes (tables' contents), no memo
        self.indices: dict[tuple[tuple[int, ...], tuple[int, ...], int], _Fn] = {}
        self.shapes: dict[int, tuple[frozenset[str], int]] = {}
        #: Valuation grids of the tables, by (columns, lows, shape): see ``_grid``.
        self.grids: dict[tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]], IntArray] = {}
        self._keys: dict[tuple[Any, ...], int] = {}
        self._by_id: dict[int, tuple[Expr, int]] = {}

    def key(self, expr: Expr) -> int:
        """A number per structurally distinct expression (equal iff the nodes compare equal).

        Hashing a frozen node hashes its whole subtree, at every level; numbering
        subtrees bottom-up, by object, makes each lookup O(1).
        """
        found = self._by_id.get(id(expr))
        if found is not None and found[0] is expr:
            return found[1]
        stack: list[tuple[Any, bool]] = [(expr, False)]
        while stack:
            node, ready = stack.pop()
            if ready:
                self._number(node)
                continue
            found = self._by_id.get(id(node))
            if found is not None and found[0] is node:
                continue
            stack.append((node, True))
            stack.extend([(child, False) for child in reversed(_key_children(node))])
        return self._by_id[id(expr)][1]

    def _number(self, expr: Any) -> None:
        """Number *expr*, whose sub-expressions are numbered."""
        parts: tuple[Any, ...]
        if isinstance(expr, Binary):
            parts = (Binary, expr.op, self.key(expr.left), self.key(expr.right))
        elif isinstance(expr, Ident):
            parts = (Ident, expr.name)
        elif isinstance(expr, IntLit | DoubleLit | BoolLit):
            parts = (type(expr), type(expr.value), expr.value)
        elif isinstance(expr, Ite):
            parts = (Ite, self.key(expr.cond), self.key(expr.then), self.key(expr.otherwise))
        elif isinstance(expr, Unary):
            parts = (Unary, expr.op, self.key(expr.operand))
        else:
            parts = (type(expr), *(self._field_key(getattr(expr, f.name))
                                   for f in dataclasses.fields(expr)
                                   if f.compare))
        number = self._keys.setdefault(parts, len(self._keys))
        self._by_id[id(expr)] = (expr, number)  # the reference keeps the id unique

    def _field_key(self, value: Any) -> Any:
        if isinstance(value, tuple):
            return (tuple, *(self._field_key(v) for v in value))
        if _is_node(value):
            return (Expr, self.key(value))
        return (type(value), value)


def _is_node(value: Any) -> bool:
    return dataclasses.is_dataclass(value) and not isinstance(value, type)


def _key_children(expr: Any) -> list[Any]:
    """The sub-expressions a key is made of, in the order :meth:`CompileCache.key` reads."""
    if isinstance(expr, Binary):
        return [expr.left, expr.right]
    if isinstance(expr, Ite):
        return [expr.cond, expr.then, expr.otherwise]
    if isinstance(expr, Unary):
        return [expr.operand]
    if isinstance(expr, Ident | IntLit | DoubleLit | BoolLit):
        return []
    found: list[Any] = []
    pending = [getattr(expr, f.name) for f in dataclasses.fields(expr) if f.compare]
    while pending:  # fields in order, tuples opened in place
        value = pending.pop(0)
        if isinstance(value, tuple):
            pending[:0] = value
        elif _is_node(value):
            found.append(value)
    return found


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
    node = _compile(expr, _Scope(columns, label_masks, ranges, cache))

    fn = node.fn

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


def variables_of(expr: Expr) -> set[str]:
    """The identifiers that occur in *expr*."""
    return set(_shape_of(expr)[0])


# ---------------------------------------------------------------------------
# Leaves
# ---------------------------------------------------------------------------


def _compile(expr: Expr, scope: _Scope) -> _Node:
    """The compiled node of *expr*: operands first, each sub-expression once (per
    cache), on an explicit stack, in the order a recursive compiler would go."""
    done: dict[int, _Node] = {}
    stack: list[tuple[Expr, bool]] = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        if ready:
            done[id(node)] = _finished(node, [done[id(c)] for c in _children(node)], scope)
            continue
        if id(node) in done:
            continue
        found = _cached(node, scope)
        if found is not None:
            done[id(node)] = found
            continue
        operands = _operands(node)
        if not operands:
            done[id(node)] = _finished(node, [], scope)
            continue
        stack.append((node, True))
        stack.extend([(operand, False) for operand in reversed(operands)])
    return done[id(expr)]


def _store(scope: _Scope) -> dict[int, _Node] | None:
    cache = scope.cache
    if cache is None:
        return None
    return cache.nodes if scope.ranges is not None else cache.plain


def _cached(expr: Expr, scope: _Scope) -> _Node | None:
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
        return _children(expr)
    raise PrismSemanticError(
        f"{type(expr).__name__} is not allowed in a state expression", expr.span
    )


def _finished(expr: Expr, operands: list[_Node], scope: _Scope) -> _Node:
    """The node of *expr* from its compiled operands: tabulated if worth it, and stored."""
    cache = scope.cache
    if scope.ranges is not None and _worth_tabulating(expr, scope.ranges, cache):
        node = _tabulated(expr, operands, scope)
    else:
        node = _compile_node(expr, operands, scope)
    store = _store(scope)
    if cache is not None and store is not None:
        if (scope.ranges is not None and cache.memoise
                and not (node.is_const or isinstance(expr, Ident | LabelRef))):
            node = dataclasses.replace(node, fn=_memoised(node.fn), plain=node.fn)
        store[cache.key(expr)] = node
    return node


def _memoised(fn: _Fn) -> _Fn:
    """*fn* remembering its results for the last two inputs (by identity)."""
    memo: list[Any] = [None, None, None, None]  # input, result, older input, result

    def evaluate(states: IntArray) -> Any:
        if states is memo[0]:
            return memo[1]
        if states is memo[2]:
            return memo[3]
        result = fn(states)
        memo[2], memo[3], memo[0], memo[1] = memo[0], memo[1], states, result
        return result

    return evaluate


def _compile_node(expr: Expr, operands: list[_Node], scope: _Scope) -> _Node:
    """The node of *expr* made from its compiled *operands* (a leaf has none)."""
    if isinstance(expr, IntLit):
        return _constant(np.int64(expr.value))
    if isinstance(expr, DoubleLit):
        return _constant(np.float64(expr.value))
    if isinstance(expr, BoolLit):
        return _constant(np.bool_(expr.value))
    if isinstance(expr, Ident):
        return _variable(expr, scope.columns)
    if isinstance(expr, LabelRef):
        return _label(expr, scope.labels)
    if isinstance(expr, Unary):
        return _unary(expr, operands[0])
    if isinstance(expr, Binary):
        return _binary(expr, operands[0], operands[1])
    if isinstance(expr, Ite):
        return _ite(operands[0], operands[1], operands[2])
    return _call(cast(Call, expr), operands)


def _constant(value: Any) -> _Node:
    # Evaluated as a 0-d array: numpy 2 promotes it exactly as the scalar (NEP 50),
    # but a ufunc takes it without the scalar conversion that doubles the cost of
    # ``s = 3`` on a short frontier.
    array = np.asarray(value)
    return _Node(fn=lambda _states: array, const=value, is_const=True)


def _variable(expr: Ident, columns: Mapping[str, int]) -> _Node:
    if expr.name not in columns:
        raise PrismSemanticError(f"unknown identifier '{expr.name}'", expr.span)
    column = columns[expr.name]
    return _Node(fn=lambda states: states[:, column])


def _label(expr: LabelRef, labels: Mapping[str, BoolArray] | None) -> _Node:
    if labels is None or expr.name not in labels:
        raise PrismSemanticError(f'unknown label "{expr.name}"', expr.span)
    mask = labels[expr.name]
    return _Node(fn=lambda _states: mask, labels=True)


# ---------------------------------------------------------------------------
# Lookup tables: a deep ``? :`` chain over one small variable (a distance per
# route position, a cost per wind and voltage level) costs dozens of numpy calls
# per BFS layer; tabulated over its variables' domain it costs one gather.
# ---------------------------------------------------------------------------

#: Largest number of valuations a tabulated sub-expression may range over.
TABLE_LIMIT = 1 << 17
#: Largest valuation grid kept for the tables that follow (models with many variables
#: have wide grids; those are rebuilt per table rather than held).
_GRID_KEEP_BYTES = 16 << 20


def _worth_tabulating(
    expr: Expr, ranges: Mapping[str, tuple[int, int]], cache: CompileCache | None
) -> bool:
    if isinstance(expr, IntLit | DoubleLit | BoolLit | Ident | LabelRef):
        return False
    names, size = _shape(expr, cache)
    if not names or not names <= ranges.keys():
        return False
    valuations = math.prod(ranges[n][1] - ranges[n][0] + 1 for n in names)
    return valuations <= TABLE_LIMIT and size > 2 * len(names) + 1


def _shape(expr: Expr, cache: CompileCache | None) -> tuple[frozenset[str], int]:
    """:func:`_shape_of`, memoised in *cache* by structural number when there is one."""
    if cache is None:
        return _shape_of(expr)
    found = cache.shapes.get(cache.key(expr))  # the usual case: operands are shaped
    return found if found is not None else _shapes(expr, cache.shapes, cache.key)


def _shape_of(expr: Expr) -> tuple[frozenset[str], int]:
    """The variables of *expr* and its number of nodes (shared sub-trees counted per use)."""
    return _shapes(expr, {}, id)  # the nodes live as long as *expr*: ids are stable


_Shape = tuple[frozenset[str], int]


def _shapes(expr: Expr, shapes: dict[int, _Shape], number: Callable[[Expr], int]) -> _Shape:
    """The shape of *expr*, children first, kept in *shapes* under each node's *number*."""
    stack: list[tuple[Expr, bool]] = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        key = number(node)
        if ready:
            parts = [shapes[number(c)] for c in _children(node)]
            shapes[key] = frozenset().union(*(p[0] for p in parts)), 1 + sum(p[1] for p in parts)
        elif key not in shapes:
            if isinstance(node, Ident):
                shapes[key] = frozenset((node.name,)), 1
                continue
            stack.append((node, True))
            stack.extend([(c, False) for c in reversed(_children(node))])
    return shapes[number(expr)]


def _size_at_least(expr: Expr, size: int) -> bool:
    """Whether *expr* has at least *size* nodes (as counted by :func:`_shape_of`)."""
    stack = [expr]
    while stack:
        size -= 1
        if size <= 0:
            return True
        stack.extend(_children(stack.pop()))
    return False


def _children(expr: Expr) -> tuple[Expr, ...]:
    if isinstance(expr, Unary):
        return (expr.operand,)
    if isinstance(expr, Binary):
        return (expr.left, expr.right)
    if isinstance(expr, Ite):
        return (expr.cond, expr.then, expr.otherwise)
    if isinstance(expr, Call):
        return expr.args
    return ()


def _tabulated(expr: Expr, operands: list[_Node], scope: _Scope) -> _Node:
    """*expr* as a lookup table over its variables' domain, or row-wise (its compiled
    *operands* combined) if that fails."""
    assert scope.ranges is not None
    # The table is made with the operands' evaluators without their memos: a memo
    # would keep each operand's values on the grid (an int64 per valuation) for the
    # whole search, and the nodes of a conditional over a route of thousands of
    # cells would keep thousands of them (the operands keep their own tables).
    direct = _compile_node(expr, [_without_memo(o) for o in operands], scope)
    names = sorted(_shape(expr, scope.cache)[0], key=lambda n: scope.columns[n])
    lows = [scope.ranges[n][0] for n in names]
    shape = [scope.ranges[n][1] - low + 1 for n, low in zip(names, lows, strict=True)]
    cols = [scope.columns[n] for n in names]
    grid = _grid(cols, lows, shape, len(scope.columns), scope.cache)
    try:
        table = np.broadcast_to(np.asarray(direct.fn(grid)), grid.shape[:1]).copy()
    except ModelError:  # fails on some valuation (e.g. x/y at y=0): evaluate per row
        return _compile_node(expr, operands, scope)
    return _Node(fn=_lookup(table, cols, lows, shape, scope.cache))


def _without_memo(node: _Node) -> _Node:
    return node if node.plain is None else dataclasses.replace(node, fn=node.plain)


#: Narrower types a table may be stored in, tried in order, by kind of its values.
_NARROW = {"i": (np.int8, np.int16, np.int32), "f": (np.float32,)}


def _narrowed(table: np.ndarray) -> np.ndarray:
    """*table* in the narrowest type that holds each of its values exactly (or as it is).

    A layer's lookups land at random places in a table, and an int64 table over a
    battery's charge and recharges is hundreds of kB: a dozen of them no longer fit
    the L2 cache between two layers, and the misses cost more than the widening
    back after the gather (``_lookup``).
    """
    for narrow in _NARROW.get(table.dtype.kind, ()):
        candidate = table.astype(narrow)
        if np.array_equal(candidate.astype(table.dtype), table):
            return candidate
    return table


def _grid(
    cols: list[int], lows: list[int], shape: list[int], width: int, cache: CompileCache | None
) -> IntArray:
    """Every valuation of the variables *cols* (the other columns 0), shared via *cache*
    by the tables over the same variables.
    """
    key = (tuple(cols), tuple(lows), tuple(shape))
    found = cache.grids.get(key) if cache is not None else None
    if found is None:
        found = np.zeros((math.prod(shape), width), dtype=np.int64)
        found[:, cols] = np.indices(shape).reshape(len(shape), -1).T + np.array(lows)
        if cache is not None and found.nbytes <= _GRID_KEEP_BYTES:
            cache.grids[key] = found
    return found


def _lookup(
    table: np.ndarray, cols: list[int], lows: list[int], shape: list[int],
    cache: CompileCache | None = None,
) -> _Fn:
    narrow = _narrowed(table)
    lookup = _lookup_in(narrow, cols, lows, shape, cache)
    if narrow.dtype != table.dtype:  # widened back: later arithmetic must not wrap
        return _widening(table.dtype, lookup)
    return lookup


def _lookup_in(
    table: np.ndarray, cols: list[int], lows: list[int], shape: list[int],
    cache: CompileCache | None,
) -> _Fn:
    """The lookup in *table*, stored as it is."""
    strides = [math.prod(shape[i + 1 :]) for i in range(len(shape))]
    offset = sum(low * stride for low, stride in zip(lows, strides, strict=True))
    if len(cols) == 1 and offset == 0:
        (col,) = cols
        return lambda states: table[states[:, col]]
    # Tables over the same variables share their index (computed once per input).
    key = (tuple(cols), tuple(strides), offset)
    index_of = cache.indices.get(key) if cache is not None else None
    if index_of is None:
        index_of = _index(cols, strides, offset)
        if cache is not None:
            index_of = cache.indices[key] = _memoised(index_of) if cache.memoise else index_of
    return lambda states: table[index_of(states)]


def _widening(dtype: np.dtype[Any], narrow: _Fn) -> _Fn:
    """*narrow* (a lookup in a narrowed table) with its values back in *dtype*."""
    return lambda states: narrow(states).astype(dtype)


def _index(cols: list[int], strides: list[int], offset: int) -> _Fn:
    """Mixed-radix position of each row's valuation of *cols* in a table."""
    shift = np.asarray(offset, dtype=np.int64)  # a 0-d array: see ``_constant``
    if len(cols) == 1:
        (col,) = cols
        return lambda states: states[:, col] - shift
    first, stop = min(cols), max(cols) + 1
    weights = np.zeros(stop - first, dtype=np.int64)
    weights[[c - first for c in cols]] = strides

    def evaluate(states: IntArray) -> Any:
        # One product with the strides (zero for the other columns in between)
        # instead of a multiply and an add per column: this runs for every table,
        # every layer. numpy's integer product is a plain loop, so its cost grows
        # with the columns it reads: only those from the first to the last used.
        index = states[:, first:stop] @ weights
        index -= shift
        return index

    return evaluate


# ---------------------------------------------------------------------------
# Operators
# ---------------------------------------------------------------------------


def _lift(
    op: Callable[..., Any], args: Sequence[_Node], risky: bool = False, link: Link | None = None
) -> _Node:
    """Combine *args* with *op*, folding when every argument is a constant.

    :param link: how the value follows from one operand's (default: from the first)
    """
    if all(a.is_const for a in args):
        try:
            return _constant(op(*(a.const for a in args)))
        except ModelError:
            pass  # e.g. ``N=0 ? 0 : 1/N``: only fail if the branch is ever evaluated
    return _made(
        _applied(op, [a.fn for a in args]),
        link or _operand_link(op, args),
        risky=risky or any(a.risky for a in args),
        labels=any(a.labels for a in args),
    )


def _operand_link(op: Callable[..., Any], args: Sequence[_Node]) -> Link:
    """``op`` over *args* as a link through the first operand, or through the second
    when that one heads the longer chain (``a + (b + (c + ...))``)."""
    if len(args) == 2 and args[1].spine > args[0].spine:
        first = args[0].fn
        return Link(args[1], lambda states: (first(states), states), op)
    return Link(args[0], same_rows, _rest_applied(op, [a.fn for a in args[1:]]))


def _made(fn: _Fn, link: Link, risky: bool, labels: bool) -> _Node:
    """The node made by *link* (evaluated by *fn*, or in a loop deep down a chain)."""
    below = cast(_Node, link.below)
    spine = below.spine + 1
    if spine >= SPINE_LIMIT:
        fn = unrolled(link)
    return _Node(fn=fn, risky=risky, labels=labels, link=link, spine=spine)


def _applied(op: Callable[..., Any], fns: Sequence[_Fn]) -> _Fn:
    """``op`` over the evaluated arguments (unrolled for arity 1 and 2: it runs per layer)."""
    if len(fns) == 1:
        (f,) = fns
        return lambda states: op(f(states))
    if len(fns) == 2:
        f, g = fns
        return lambda states: op(f(states), g(states))
    return lambda states: op(*(h(states) for h in fns))


def _rest_applied(op: Callable[..., Any], rest: Sequence[_Fn]) -> Callable[[Any, Any], Any]:
    """``op`` over the first argument's value and the others evaluated (a link's combine)."""
    if not rest:
        return lambda _states, value: op(value)
    if len(rest) == 1:
        (g,) = rest
        return lambda states, value: op(value, g(states))
    return lambda states, value: op(value, *(h(states) for h in rest))


def _unary(expr: Unary, operand: _Node) -> _Node:
    if expr.op == "!":
        return _lift(np.logical_not, [operand])
    return _lift(np.negative, [operand])


_SIMPLE_BINARY: dict[str, Callable[[Any, Any], Any]] = {
    "<=>": np.equal,
    "=": np.equal,
    "!=": np.not_equal,
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
    "+": np.add,
    "-": np.subtract,
    "*": np.multiply,
}


def _binary(expr: Binary, left: _Node, right: _Node) -> _Node:
    op = expr.op
    if op in ("&", "|", "=>"):
        return _logical(op, left, right, _size_at_least(expr.right, _SKIP_SIZE))
    if op == "<=>":
        return _lift(lambda a, b: np.equal(np.asarray(a, bool), np.asarray(b, bool)), [left, right])
    if op == "/":
        return _lift(lambda a, b: _divide(a, b, expr.span), [left, right], risky=True)
    return _lift(_SIMPLE_BINARY[op], [left, right])


#: Right operands of ``&``/``|`` with at least this many nodes are skipped when the
#: left operand alone decides every row (see ``_skipping``).
_SKIP_SIZE = 4


def _logical(op: str, left: _Node, right: _Node, big: bool = False) -> _Node:
    """``&``, ``|`` and ``=>``; a risky right operand is evaluated only where needed."""
    if op == "=>":
        left = _lift(np.logical_not, [left])
    combine = np.logical_and if op == "&" else np.logical_or
    if not right.subsettable or left.is_const:
        if big and not (left.is_const or right.is_const):
            return _skipping(combine, op != "&", left, right)
        return _lift(combine, [left, right])
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
                 risky=True, labels=left.labels)


def _skipping(combine: Callable[..., Any], decided_value: bool, left: _Node, right: _Node) -> _Node:
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
                 risky=left.risky or right.risky, labels=left.labels or right.labels)


def _ite(cond: _Node, then: _Node, otherwise: _Node) -> _Node:
    """``cond ? then : otherwise``, linked through the branch that heads the longer
    chain (usually *otherwise*: ``c1 ? v1 : c2 ? v2 : ...``)."""
    if cond.is_const:
        return then if bool(cond.const) else otherwise
    if not (then.subsettable or otherwise.subsettable):
        return _lift(np.where, [cond, then, otherwise], link=_both_link(cond, then, otherwise))
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
    return _made(evaluate, link, risky=True, labels=cond.labels)


def _both_link(cond: _Node, then: _Node, otherwise: _Node) -> Link:
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


def _divide(a: Any, b: Any, span: Span) -> Any:
    if np.any(np.asarray(b) == 0):
        raise ModelError("division by zero", span)
    return np.true_divide(a, b, dtype=np.float64)


# ---------------------------------------------------------------------------
# Built-in functions
# ---------------------------------------------------------------------------


def _call(expr: Call, args: list[_Node]) -> _Node:
    func, span = expr.func, expr.span
    arity = {"floor": 1, "ceil": 1, "pow": 2, "mod": 2, "log": 2}.get(func)
    if (arity is not None and len(args) != arity) or (arity is None and not args):
        raise PrismSemanticError(f"wrong number of arguments to {func}", span)
    if func in ("min", "max"):
        return _lift(lambda *xs: _reduce(np.minimum if func == "min" else np.maximum, xs), args)
    if func in ("floor", "ceil"):
        return _lift(lambda x: _round(np.floor if func == "floor" else np.ceil, x), args)
    if func == "pow":
        return _lift(lambda a, b: _power(a, b, span), args, risky=True)
    if func == "mod":
        return _lift(lambda a, b: _modulo(a, b, span), args, risky=True)
    return _lift(_log, args)


def _is_int(x: Any) -> bool:
    return np.asarray(x).dtype.kind in "iub"


def _reduce(op: Callable[[Any, Any], Any], xs: Sequence[Any]) -> Any:
    result = xs[0]
    for x in xs[1:]:
        result = op(result, x)
    return result


def _round(op: Callable[[Any], Any], x: Any) -> Any:
    if _is_int(x):
        return np.asarray(x, dtype=np.int64)[()]
    with np.errstate(invalid="ignore"):
        return np.asarray(op(x)).astype(np.int64)[()]


def _power(a: Any, b: Any, span: Span) -> Any:
    if _is_int(a) and _is_int(b):
        if np.any(np.asarray(b) < 0):
            raise ModelError("negative exponent in integer pow", span)
        return np.power(np.asarray(a, np.int64), np.asarray(b, np.int64))[()]
    with np.errstate(all="ignore"):  # Java's Math.pow: NaN/Infinity, no exception
        return np.power(np.asarray(a, np.float64), np.asarray(b, np.float64))[()]


def _modulo(a: Any, b: Any, span: Span) -> Any:
    if not (_is_int(a) and _is_int(b)):
        raise ModelError("mod requires integer arguments", span)
    if np.any(np.asarray(b) <= 0):
        raise ModelError("modulo with non-positive divisor", span)
    # PRISM returns a result in 0..b-1 even for negative a: numpy's (Python's) convention.
    return np.mod(np.asarray(a, np.int64), np.asarray(b, np.int64))[()]


def _log(x: Any, base: Any) -> Any:
    with np.errstate(all="ignore"):  # Java's Math.log: NaN/-Infinity, no exception
        return (np.log(np.asarray(x, np.float64)) / np.log(np.asarray(base, np.float64)))[()]


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
    node = _compile(expr, _Scope(columns, cache=cache))
    return node.const.item() if node.is_const else None
