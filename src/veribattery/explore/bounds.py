"""Interval analysis of expressions: which updates provably stay in range.

Used to skip per-state range checks in the builder and whole commands in the
domain-wide check. Pure AST analysis: a sound over-approximation, or None.
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
    if isinstance(expr, IntLit | DoubleLit | BoolLit):
        return (float(expr.value), float(expr.value))
    if isinstance(expr, Ident):
        return bounds.get(expr.name)
    if isinstance(expr, Unary):
        inner = value_bounds(expr.operand, bounds)
        if expr.op == "!" or inner is None:
            return (0.0, 1.0) if expr.op == "!" else None
        return (-inner[1], -inner[0])
    if isinstance(expr, Binary):
        return _binary_bounds(expr, bounds)
    if isinstance(expr, Ite):
        return _hull([value_bounds(expr.then, bounds), value_bounds(expr.otherwise, bounds)])
    if isinstance(expr, Call) and expr.func in ("min", "max"):
        return _min_max_bounds(expr, bounds)
    return None


def _binary_bounds(expr: Binary, bounds: Mapping[str, Bounds]) -> Bounds | None:
    if expr.op in _RELATIONAL:
        return (0.0, 1.0)
    left, right = value_bounds(expr.left, bounds), value_bounds(expr.right, bounds)
    if left is None or right is None or expr.op == "/":
        return None
    if expr.op == "+":
        return (left[0] + right[0], left[1] + right[1])
    if expr.op == "-":
        return (left[0] - right[1], left[1] - right[0])
    products = [a * b for a in left for b in right]
    return (min(products), max(products))


def _min_max_bounds(expr: Call, bounds: Mapping[str, Bounds]) -> Bounds | None:
    args = [value_bounds(a, bounds) for a in expr.args]
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
