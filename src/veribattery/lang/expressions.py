"""Generic expression plumbing: walking, substitution, literals and constant folding."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from typing import Any, cast

from veribattery.errors import NO_SPAN, Span
from veribattery.lang import nodes
from veribattery.lang.evaluate import EvaluationError, evaluate
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

_NODE_TYPES = tuple(
    obj
    for obj in vars(nodes).values()
    if isinstance(obj, type) and dataclasses.is_dataclass(obj) and obj.__module__ == nodes.__name__
)
_LITERALS = (IntLit, DoubleLit, BoolLit)


def _is_node(value: object) -> bool:
    return isinstance(value, _NODE_TYPES)


def children(node: Any) -> Iterator[Any]:
    """The direct sub-nodes of an AST node (expressions, paths, bounds)."""
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if _is_node(value):
            yield value
        elif isinstance(value, tuple):
            yield from (v for v in value if _is_node(v))


def walk(node: Any) -> Iterator[Any]:
    """*node* and all nodes below it, parents first."""
    yield node
    for child in children(node):
        yield from walk(child)


def substitute(node: Any, replace: Callable[[Any], Any | None]) -> Any:
    """Rebuild *node*, replacing each sub-node for which *replace* returns a value.

    The replacement is not visited again, so a formula body substituted for its name
    is not renamed twice.
    """
    new = replace(node)
    if new is not None:
        return new
    changes: dict[str, Any] = {}
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if _is_node(value):
            changes[f.name] = substitute(value, replace)
        elif isinstance(value, tuple) and any(_is_node(v) for v in value):
            changes[f.name] = tuple(substitute(v, replace) if _is_node(v) else v for v in value)
    return dataclasses.replace(node, **changes) if changes else node


def rename_idents(expr: Expr, mapping: dict[str, Expr]) -> Expr:
    """Replace identifiers by expressions, simultaneously."""

    def replace(node: Any) -> Any | None:
        if isinstance(node, Ident) and node.name in mapping:
            return mapping[node.name]
        return None

    return cast(Expr, substitute(expr, replace))


def literal(value: Value, span: Span = NO_SPAN, kind: ValueType | None = None) -> Expr:
    """The literal node for a value; *kind* forces the type (an int value of a double)."""
    if isinstance(value, bool):
        return BoolLit(value, span)
    if kind == "double" or isinstance(value, float):
        return DoubleLit(float(value), repr(float(value)), span)
    return IntLit(value, span)


def fold(node: Any) -> Any:
    """Replace closed arithmetic/boolean sub-expressions of *node* by their value.

    Sub-expressions whose evaluation fails (``mod(x, 0)``, a negative int power)
    are left alone, so that the error is reported where the expression is used.
    """
    node = _fold_children(node)
    if not isinstance(node, Unary | Binary | Ite | Call):
        return node
    if not all(isinstance(c, _LITERALS) for c in children(node)):
        return node
    try:
        value = evaluate(node, {})
    except EvaluationError:
        return node
    return literal(value, node.span, "double" if _double_ite(node) else None)


def _fold_children(node: Any) -> Any:
    changes: dict[str, Any] = {}
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if _is_node(value):
            changes[f.name] = fold(value)
        elif isinstance(value, tuple) and any(_is_node(v) for v in value):
            changes[f.name] = tuple(fold(v) if _is_node(v) else v for v in value)
    return dataclasses.replace(node, **changes) if changes else node


def _double_ite(node: Expr) -> bool:
    """An ``?:`` with an int and a double branch has type double whichever branch wins."""
    return isinstance(node, Ite) and (
        isinstance(node.then, DoubleLit) or isinstance(node.otherwise, DoubleLit)
    )
