"""Interval analysis of expressions: which updates provably stay in range.

Used to skip per-state range checks in the builder and whole commands in the
domain-wide check. Pure AST analysis: a sound over-approximation, or None. It keeps
its own stack: an expression may be a chain of thousands of ``? :``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from veribattery.lang.nodes import Binary, BoolLit, Call, DoubleLit, Expr, Ident, IntLit, Ite, Unary

__all__ = ["Bounds", "value_bounds"]

Bounds = tuple[float, float]
_RELATIONAL = frozenset({"=", "!=", "<", "<=", ">", ">=", "&", "|", "=>", "<=>"})


def value_bounds(expr: Expr, bounds: Mapping[str, Bounds]) -> Bounds | None:
    """An interval containing every value of *expr* given its variables' *bounds*.

    None when unknown (division, ``pow``, ``mod`` ...): callers then check at run time.
    """
    found: dict[int, Bounds | None] = {}
    stack: list[tuple[Expr, bool]] = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        if ready:
            found[id(node)] = _combined(node, [found[id(o)] for o in _operands(node)], bounds)
            continue
        if id(node) in found:
            continue
        operands = _operands(node)
        if not operands:
            found[id(node)] = _combined(node, (), bounds)
            continue
        stack.append((node, True))
        stack.extend([(o, False) for o in reversed(operands)])
    return found[id(expr)]


def _operands(expr: Expr) -> tuple[Expr, ...]:
    """The operands whose bounds the bounds of *expr* are made of."""
    if isinstance(expr, Unary):
        return (expr.operand,) if expr.op == "-" else ()
    if isinstance(expr, Binary):
        return () if expr.op in _RELATIONAL else (expr.left, expr.right)
    if isinstance(expr, Ite):
        return (expr.then, expr.otherwise)
    if isinstance(expr, Call) and expr.func in ("min", "max"):
        return expr.args
    return ()


def _combined(
    expr: Expr, parts: Sequence[Bounds | None], bounds: Mapping[str, Bounds]
) -> Bounds | None:
    """The bounds of *expr* from those of its operands (*bounds*: the variables')."""
    if isinstance(expr, IntLit | DoubleLit | BoolLit):
        return (float(expr.value), float(expr.value))
    if isinstance(expr, Ident):
        return bounds.get(expr.name)
    if isinstance(expr, Unary):
        if expr.op == "!" or parts[0] is None:
            return (0.0, 1.0) if expr.op == "!" else None
        return (-parts[0][1], -parts[0][0])
    if isinstance(expr, Binary):
        return _binary_bounds(expr, parts)
    if isinstance(expr, Ite):
        return _hull(parts)
    if isinstance(expr, Call) and expr.func in ("min", "max"):
        return _min_max_bounds(expr, parts)
    return None


def _binary_bounds(expr: Binary, parts: Sequence[Bounds | None]) -> Bounds | None:
    if expr.op in _RELATIONAL:
        return (0.0, 1.0)
    left, right = parts
    if left is None or right is None or expr.op == "/":
        return None
    if expr.op == "+":
        return (left[0] + right[0], left[1] + right[1])
    if expr.op == "-":
        return (left[0] - right[1], left[1] - right[0])
    products = [a * b for a in left for b in right]
    return (min(products), max(products))


def _min_max_bounds(expr: Call, args: Sequence[Bounds | None]) -> Bounds | None:
    known = [a for a in args if a is not None]
    if len(known) < len(args):
        return None
    pick = min if expr.func == "min" else max
    return (pick(a[0] for a in known), pick(a[1] for a in known))


def _hull(parts: Sequence[Bounds | None]) -> Bounds | None:
    if any(p is None for p in parts):
        return None
    known = [p for p in parts if p is not None]
    return (min(p[0] for p in known), max(p[1] for p in known))
