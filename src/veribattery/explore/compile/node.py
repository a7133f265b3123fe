"""The compiled form of an expression: nodes, the compilation scope, the shared cache.

A :class:`Node` is a compiled sub-expression (an evaluator over an ``(n, n_vars)``
array of variable values, or a folded constant) with what the compiler knows about
it; :class:`CompileCache` shares nodes, tables and their results across the
expressions of one program.
"""

from __future__ import annotations

import dataclasses
import math
import weakref
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.explore.compile.chains import Link
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    DoubleLit,
    Expr,
    Ident,
    IntLit,
    Ite,
    Unary,
)

__all__ = ["CompileCache", "CompiledExpr", "Fn", "Node", "Scope", "constant_node", "memoised"]


#: The public shape of a compiled expression.
CompiledExpr = Callable[[IntArray], np.ndarray]
# Internal evaluators may return a numpy scalar where the value is constant.
Fn = Callable[[IntArray], Any]


@dataclass(frozen=True, slots=True)
class Node:
    """A compiled sub-expression: an evaluator, or a folded constant."""

    fn: Fn
    const: Any = None
    is_const: bool = False
    risky: bool = False  # may raise on some rows
    labels: bool = False  # reads label masks (aligned with all rows: no row subsets)
    link: Link | None = None  # how the value follows from its deepest operand's
    spine: int = 0  # links in a row down from here: evaluated in a loop from SPINE_LIMIT
    size: int = 1  # operations per row, at most (capped): what evaluating it costs
    double: bool = False  # PRISM type double (else int or bool)
    noisy: bool = False  # evaluates an operand that may be infinite or NaN (numpy warns)

    @property
    def subsettable(self) -> bool:
        """Whether evaluating this node on a subset of rows is both useful and safe."""
        return self.risky and not self.labels


@dataclass(frozen=True, slots=True)
class Scope:
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
        self.nodes: dict[int, Node] = {}
        self.plain: dict[int, Node] = {}  # row-wise nodes (tables' contents), no memo
        self.indices: dict[tuple[tuple[int, ...], tuple[int, ...], int], Fn] = {}
        self.shapes: dict[int, tuple[frozenset[str], int]] = {}
        #: Valuation grids of the tables, by (columns, lows, shape): see ``valuation_grid``.
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
            parts = (type(expr), type(expr.value), expr.value, _zero_sign(expr.value))
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


def _zero_sign(value: bool | int | float) -> float:
    """The sign of a float (-0.0 == 0.0, but 1/-0.0 is -inf: the sign tells them
    apart); 1 for an int or bool, which has no negative zero and may be too large for
    a float."""
    return math.copysign(1.0, value) if isinstance(value, float) else 1.0


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


def memoised(fn: Fn) -> Fn:
    """*fn* remembering its results for the last two inputs (by identity) while those
    inputs live: the memo holds them by weak reference and drops a result with its
    input, so the memos of a program's many nodes keep no frontier array alive after
    its layer (on egl N=7 they kept 483 MB of per-command frontiers to the end)."""
    memo: list[Any] = [None, None, None, None]  # input ref, result, older ref, result

    def forget(ref: weakref.ref[Any]) -> None:
        for slot in (0, 2):
            if memo[slot] is ref:
                memo[slot] = memo[slot + 1] = None

    def evaluate(states: IntArray) -> Any:
        newer, older = memo[0], memo[2]
        if newer is not None and newer() is states:
            return memo[1]
        if older is not None and older() is states:
            return memo[3]
        result = fn(states)
        memo[2], memo[3] = newer, memo[1]
        memo[0], memo[1] = weakref.ref(states, forget), result
        return result

    return evaluate


def constant_node(value: Any) -> Node:
    # Evaluated as a 0-d array: numpy 2 promotes it exactly as the scalar (NEP 50),
    # but a ufunc takes it without the scalar conversion that doubles the cost of
    # ``s = 3`` on a short frontier.
    array = np.asarray(value)
    return Node(fn=lambda _states: array, const=value, is_const=True)
