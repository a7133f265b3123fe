"""The expression traversals: walk order, substitution, folding, and per-node sharing."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

from tests.lang.helpers import peer_files
from veribattery.errors import PrismSemanticError
from veribattery.lang import (
    Binary,
    BoolLit,
    Call,
    DoubleLit,
    Ident,
    IntLit,
    Ite,
    Unary,
    flatten_model,
    nodes,
    parse_model,
)
from veribattery.lang.evaluate import EvaluationError, evaluate
from veribattery.lang.expressions import close, fold, literal, substitute, walk
from veribattery.lang.semantics import expand_formulas

_NODES = tuple(
    obj
    for obj in vars(nodes).values()
    if isinstance(obj, type) and dataclasses.is_dataclass(obj)
    and obj.__module__.startswith(f"{nodes.__name__}.")  # the modules of lang.nodes
)
_LITERALS = (IntLit, DoubleLit, BoolLit)


def _node_children(node: Any) -> list[Any]:
    found: list[Any] = []
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if isinstance(value, _NODES):
            found.append(value)
        elif isinstance(value, tuple):
            found.extend(v for v in value if isinstance(v, _NODES))
    return found


def _reference_substitute(node: Any, replace: Any) -> Any:
    """The plain dataclass-fields substitution the fast traversals must agree with."""
    new = replace(node)
    if new is not None:
        return new
    return _map_children(node, lambda v: _reference_substitute(v, replace))


def _map_children(node: Any, visit: Any) -> Any:
    changes: dict[str, Any] = {}
    for f in dataclasses.fields(node):
        value = getattr(node, f.name)
        if isinstance(value, _NODES):
            changes[f.name] = visit(value)
        elif isinstance(value, tuple) and any(isinstance(v, _NODES) for v in value):
            changes[f.name] = tuple(visit(v) if isinstance(v, _NODES) else v for v in value)
    return dataclasses.replace(node, **changes) if changes else node


def _reference_fold(node: Any) -> Any:
    """The plain dataclass-fields constant folding the fast traversals must agree with."""
    node = _map_children(node, _reference_fold)
    if not isinstance(node, Unary | Binary | Ite | Call):
        return node
    if not all(isinstance(c, _LITERALS) for c in _node_children(node)):
        return node
    try:
        value = evaluate(node, {})
    except EvaluationError:
        return node
    double = isinstance(node, Ite) and (
        isinstance(node.then, DoubleLit) or isinstance(node.otherwise, DoubleLit)
    )
    return literal(value, node.span, "double" if double else None)


def _deep(node: Any) -> Any:
    """A structural dump that includes spans (which == ignores)."""
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        fields = dataclasses.fields(node)
        return (type(node).__name__, *((f.name, _deep(getattr(node, f.name))) for f in fields))
    if isinstance(node, tuple):
        return tuple(_deep(v) for v in node)
    return (type(node).__name__, repr(node))


def test_walk_is_parents_first_left_to_right() -> None:
    expr = parse_model("dtmc\nformula f = (a + b) * -c;\n").formulas[0].expr
    names = [type(n).__name__ + (f":{n.name}" if isinstance(n, Ident) else "") for n in walk(expr)]
    assert names == ["Binary", "Binary", "Ident:a", "Ident:b", "Unary", "Ident:c"]


def test_substitute_does_not_revisit_replacements() -> None:
    expr = Binary("+", Ident("a"), Ident("b"))
    swapped = substitute(
        expr, lambda n: Ident("b" if n.name == "a" else "a") if isinstance(n, Ident) else None
    )
    assert swapped == Binary("+", Ident("b"), Ident("a"))


def test_shared_subtrees_are_visited_once() -> None:
    shared = Binary("+", Ident("x"), IntLit(1))
    expr = Binary("*", shared, shared)
    seen: list[Any] = []
    substitute(expr, lambda n: seen.append(n))
    assert sum(n is shared for n in seen) == 1
    out = substitute(expr, lambda n: IntLit(2) if isinstance(n, Ident) else None)
    assert out.left is out.right and out.left == Binary("+", IntLit(2), IntLit(1))


def test_fold_leaves_failing_expressions_alone() -> None:
    expr = Call("mod", (IntLit(7), IntLit(0)))
    assert fold(expr) is expr
    assert fold(Binary("+", IntLit(2), IntLit(3))) == IntLit(5)


def test_close_is_substitute_then_fold() -> None:
    model = parse_model("dtmc\nconst double p = 1;\nformula f = x > 0 ? p : 2;\n")
    expr = model.formulas[0].expr
    closed = close(expr, {"p": 1}, {"p": "double"}, {})
    assert _deep(closed) == _deep(
        _reference_fold(
            _reference_substitute(
                expr,
                lambda n: (
                    literal(1, n.span, "double") if isinstance(n, Ident) and n.name == "p" else None
                ),
            )
        )
    )


def test_a_type_error_in_a_shared_formula_is_reported_at_its_body() -> None:
    text = (
        "dtmc\nformula f = x + true;\n"
        "module m x : [0..2]; [] f > 0 -> (x'=0); [] f < 1 -> (x'=1); endmodule\n"
    )
    with pytest.raises(PrismSemanticError, match="cannot be applied to int and bool") as info:
        flatten_model(parse_model(text))
    span = info.value.span
    assert span is not None and (span.line, span.col) == (2, 13)


@pytest.mark.parametrize("path", peer_files(".pm", ".prism"))
def test_fast_traversals_agree_with_the_reference(path: Path) -> None:
    model = parse_model(path)
    formulas = expand_formulas(model.formulas)

    def inline(node: Any) -> Any | None:
        return formulas[node.name] if isinstance(node, Ident) and node.name in formulas else None

    def reference_closed(node: Any) -> Any:
        return _reference_fold(_reference_substitute(node, inline))

    for module in model.modules:
        assert _deep(fold(substitute(module, inline))) == _deep(reference_closed(module))
        assert list(walk(module)) == _reference_walk(module)


def _reference_walk(node: Any) -> list[Any]:
    return [node, *(n for child in _node_children(node) for n in _reference_walk(child))]
