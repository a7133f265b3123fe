"""Generic expression plumbing: walking, substitution, literals and constant folding.

The expression types (literals, names, ``Unary``/``Binary``/``Ite``/``Call``) make up
nearly every node of a model, so each traversal handles them directly and falls back
to the dataclass fields only for the other node types. Each traversal also remembers
its result per node object: formulas are inlined as shared sub-trees, and a shared
sub-tree is then visited once, not once per use.

No traversal here recurses in Python: a model may hold a 5,000-term disjunction or a
conditional nested thousands deep (a value per cell of a large farm), far beyond the
interpreter's recursion limit. They keep their own stack (:func:`_bottom_up`) and
visit nodes in the order a recursive traversal would.
"""

from __future__ import annotations

import dataclasses
import operator
from collections.abc import Callable, Iterator, Mapping
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
    LabelRef,
    Unary,
    Value,
    ValueType,
)

_NODE_TYPES = tuple(
    obj
    for obj in vars(nodes).values()
    if isinstance(obj, type) and dataclasses.is_dataclass(obj)
    and obj.__module__.startswith(f"{nodes.__name__}.")  # the modules of lang.nodes
)
# Node classes are never subclassed: a type lookup in a set is what isinstance against
# ~50 classes costs, several times over (it dominated the semantic pass on large models).
_NODE_TYPE_SET = frozenset(_NODE_TYPES)
_LITERALS = (IntLit, DoubleLit, BoolLit)
_LITERAL_TYPES = frozenset(_LITERALS)
#: The operator nodes: closed ones are folded.
_OPERATORS = frozenset({Binary, Ite, Unary, Call})
#: Node types without sub-nodes.
_LEAVES = frozenset({IntLit, DoubleLit, BoolLit, Ident, LabelRef})
#: Field names per node type, in declaration order (``dataclasses.fields`` is slow).
_FIELDS: dict[type, tuple[str, ...]] = {
    cls: tuple(f.name for f in dataclasses.fields(cls)) for cls in _NODE_TYPES
}

#: Results of one traversal per node object; the node is kept so that its id stays valid.
Memo = dict[int, tuple[Any, Any]]


def _is_node(value: object) -> bool:
    return type(value) in _NODE_TYPE_SET


def _child_nodes(node: Any) -> tuple[Any, ...]:
    cls = type(node)
    if cls is Binary:
        return (node.left, node.right)
    if cls is Ite:
        return (node.cond, node.then, node.otherwise)
    if cls is Unary:
        return (node.operand,)
    if cls is Call:
        return tuple(a for a in node.args if _is_node(a))
    if cls in _LEAVES:
        return ()
    found: list[Any] = []
    for name in _FIELDS[cls]:
        value = getattr(node, name)
        if _is_node(value):
            found.append(value)
        elif isinstance(value, tuple):
            found.extend(v for v in value if _is_node(v))
    return tuple(found)


def children(node: Any) -> Iterator[Any]:
    """The direct sub-nodes of an AST node (expressions, paths, bounds)."""
    return iter(_child_nodes(node))


def operand_chain(expr: Expr, op: str) -> list[Expr]:
    """The operands of the chain of *op* (``&`` or ``|``) *expr* heads, left to right,
    however it is nested."""
    operands: list[Expr] = []
    stack: list[Expr] = [expr]
    while stack:
        node = stack.pop()
        if isinstance(node, Binary) and node.op == op:
            stack += (node.right, node.left)
        else:
            operands.append(node)
    return operands


def walk(node: Any) -> Iterator[Any]:
    """*node* and all nodes below it, parents first."""
    stack = [node]
    while stack:
        current = stack.pop()
        yield current
        stack.extend(reversed(_child_nodes(current)))


def _rebuild(node: Any, visit: Callable[[Any], Any]) -> Any:
    """*node* with *visit* applied to each direct sub-node (*node* itself if none changes)."""
    cls = type(node)
    if cls is Binary:
        left, right = visit(node.left), visit(node.right)
        if left is node.left and right is node.right:
            return node
        return Binary(node.op, left, right, node.span)
    if cls is Ite:
        cond, then, otherwise = visit(node.cond), visit(node.then), visit(node.otherwise)
        if cond is node.cond and then is node.then and otherwise is node.otherwise:
            return node
        return Ite(cond, then, otherwise, node.span)
    if cls is Unary:
        operand = visit(node.operand)
        return node if operand is node.operand else Unary(node.op, operand, node.span)
    if cls is Call:
        old = node.args
        args = tuple([visit(a) if type(a) in _NODE_TYPE_SET else a for a in old])
        if not any(map(operator.is_not, args, old)):
            return node
        return Call(node.func, args, node.span)
    if cls in _LEAVES:
        return node
    return _rebuild_fields(node, visit)


def _rebuild_fields(node: Any, visit: Callable[[Any], Any]) -> Any:
    """:func:`_rebuild` for the node types other than expressions, field by field."""
    cls = type(node)
    values = []
    changed = False
    for name in _FIELDS[cls]:
        value = getattr(node, name)
        if _is_node(value):
            new = visit(value)
        elif isinstance(value, tuple) and any(_is_node(v) for v in value):
            new = tuple(visit(v) if _is_node(v) else v for v in value)
            changed = changed or any(a is not b for a, b in zip(new, value, strict=True))
            values.append(new)
            continue
        else:
            new = value
        changed = changed or new is not value
        values.append(new)
    return cls(*values) if changed else node


def _bottom_up(
    root: Any,
    pre: Callable[[Any], Any | None],
    post: Callable[[Any, Callable[[Any], Any]], Any],
    memo: Memo,
) -> Any:
    """The result for *root*, computed children first on an explicit stack.

    *pre* is asked for each node before its children: a value is the node's result
    (its children are not visited), None visits them. *post* then makes the node's
    result, reading its children's through the lookup it is given. Each node object
    is handled once (*memo*, which also keeps each node alive so that its id stays
    valid), left to right and children first, as the recursion it replaces did.
    """
    hit = memo.get(id(root))
    if hit is not None:
        return hit[1]

    def result(sub: Any) -> Any:
        return memo[id(sub)][1]

    stack: list[tuple[Any, bool]] = [(root, False)]
    while stack:
        node, expanded = stack.pop()
        key = id(node)
        if expanded:
            memo[key] = (node, post(node, result))
            continue
        if key in memo:  # a sub-tree shared with one visited since it was pushed
            continue
        new = pre(node)
        if new is not None:
            memo[key] = (node, new)
            continue
        kids = _child_nodes(node)
        if not kids:
            memo[key] = (node, post(node, result))
            continue
        stack.append((node, True))
        stack.extend([(child, False) for child in reversed(kids)])
    return memo[id(root)][1]


def substitute(node: Any, replace: Callable[[Any], Any | None]) -> Any:
    """Rebuild *node*, replacing each sub-node for which *replace* returns a value.

    The replacement is not visited again, so a formula body substituted for its name
    is not renamed twice. *replace* must give the same answer for the same node
    object: a shared sub-tree is visited once.
    """
    return _bottom_up(node, replace, _rebuild, {})


def rename_idents(expr: Expr, mapping: dict[str, Expr]) -> Expr:
    """Replace identifiers by expressions, simultaneously."""

    def replace(node: Any) -> Any | None:
        if type(node) is Ident and node.name in mapping:
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
    return close(node, {}, {}, {})


def close(
    node: Any, values: Mapping[str, Value], types: Mapping[str, ValueType], memo: Memo
) -> Any:
    """*node* with the constants of *values* replaced by literals (typed per *types*),
    then folded (as :func:`fold`), in one pass.

    *memo* keeps the result per node object; pass the same dict to calls with the
    same *values* to share the work on shared sub-trees.
    """

    def constant(sub: Any) -> Any | None:
        if type(sub) is not Ident:
            return None
        name = sub.name
        return literal(values[name], sub.span, types[name]) if name in values else sub

    return _bottom_up(node, constant, _folded, memo)


def _folded(node: Any, visit: Callable[[Any], Any]) -> Any:
    """*node* rebuilt from its visited children, evaluated if they are all literals."""
    new = _rebuild(node, visit)
    if type(node) in _OPERATORS and all(type(c) in _LITERAL_TYPES for c in _child_nodes(new)):
        return _evaluated(new)
    return new


def _evaluated(node: Expr) -> Expr:
    """The literal value of *node*, whose operands are literals, or *node* if it fails."""
    try:
        value = evaluate(node, {})
    except EvaluationError:
        return node
    return literal(value, node.span)  # a double ``? :`` gives a float: evaluate types it
