"""The shape of an expression: its variables and its size, computed without recursion.

The compiler tabulates a sub-expression when its variables span few valuations and it
is big enough to be worth it; these walks tell which.
"""

from __future__ import annotations

from collections.abc import Callable

from veribattery.explore.compile.node import CompileCache
from veribattery.lang.nodes import (
    Binary,
    Call,
    Expr,
    Ident,
    Ite,
    Unary,
)

__all__ = ["cached_shape", "shape_of", "size_at_least", "sub_expressions"]


def cached_shape(expr: Expr, cache: CompileCache | None) -> tuple[frozenset[str], int]:
    """:func:`shape_of`, memoised in *cache* by structural number when there is one."""
    if cache is None:
        return shape_of(expr)
    found = cache.shapes.get(cache.key(expr))  # the usual case: operands are shaped
    return found if found is not None else _shapes(expr, cache.shapes, cache.key)


def shape_of(expr: Expr) -> tuple[frozenset[str], int]:
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
            parts = [shapes[number(c)] for c in sub_expressions(node)]
            shapes[key] = frozenset().union(*(p[0] for p in parts)), 1 + sum(p[1] for p in parts)
        elif key not in shapes:
            if isinstance(node, Ident):
                shapes[key] = frozenset((node.name,)), 1
                continue
            stack.append((node, True))
            stack.extend([(c, False) for c in reversed(sub_expressions(node))])
    return shapes[number(expr)]


def size_at_least(expr: Expr, size: int) -> bool:
    """Whether *expr* has at least *size* nodes (as counted by :func:`shape_of`)."""
    stack = [expr]
    while stack:
        size -= 1
        if size <= 0:
            return True
        stack.extend(sub_expressions(stack.pop()))
    return False


def sub_expressions(expr: Expr) -> tuple[Expr, ...]:
    if isinstance(expr, Unary):
        return (expr.operand,)
    if isinstance(expr, Binary):
        return (expr.left, expr.right)
    if isinstance(expr, Ite):
        return (expr.cond, expr.then, expr.otherwise)
    if isinstance(expr, Call):
        return expr.args
    return ()
