"""The model's and a properties file's constants, in exact rational arithmetic.

``const double p = 1/3`` is 1/3 and ``--const p=0.7`` is 7/10, where the flattening
computes doubles: the exact engine (:mod:`~veribattery.explore.exact`) reads these.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence

from gmpy2 import mpq, mpz

from veribattery.explore.exact.rational import ExactScalar, evaluate_rational, rational
from veribattery.lang.constants import given_expression
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import ConstDecl, Ident, Value

__all__ = ["exact_constants"]



def exact_constants(
    decls: Sequence[ConstDecl],
    given: Mapping[str, Value | str],
    outer: Mapping[str, ExactScalar] | None = None,
) -> dict[str, ExactScalar]:
    """Exact values of *decls* (defined ones evaluated rationally, undefined from *given*).

    The flattening (:func:`~veribattery.lang.flatten_model`) has already
    checked names, types and cycles; this only recomputes the values without
    rounding: ``const double p = 1/3`` is 1/3, ``--const p=0.7`` is 7/10.
    """
    values: dict[str, ExactScalar] = dict(outer or {})
    pending = {d.name: d for d in decls}
    uses = {d.name: _constants_used(d, pending) for d in decls}
    defined = _defined(uses, pending, given)
    for decl in decls:
        if defined[decl.name]:
            for name in _dependencies_first(decl.name, uses, values.keys()):
                values[name] = _constant(pending[name], given, values)
    return values


def _constants_used(decl: ConstDecl, pending: Mapping[str, ConstDecl]) -> list[str]:
    """The constants of *pending* that *decl* is defined with, in order of appearance."""
    if decl.value is None:
        return []
    return [n.name for n in walk(decl.value) if isinstance(n, Ident) and n.name in pending]


def _dependencies_first(
    name: str, uses: Mapping[str, list[str]], known: Collection[str]
) -> list[str]:
    """*name* and the constants it needs that are not *known*, each after those it
    uses (depth first, in order of appearance; a stack of its own: chains are long)."""
    order: list[str] = []
    placed = set(known)
    todo: list[tuple[str, bool]] = [(name, False)]
    while todo:
        current, ready = todo.pop()
        if ready:
            order.append(current)
        elif current not in placed:
            placed.add(current)  # flattening rejected cycles: each name is entered once
            todo.append((current, True))
            todo.extend((n, False) for n in reversed(uses[current]))
    return order


def _defined(
    uses: Mapping[str, list[str]], pending: Mapping[str, ConstDecl], given: Mapping[str, object]
) -> dict[str, bool]:
    """Per constant, whether it has a value: given, or defined from constants that
    all have one.

    A properties file may declare a constant it never uses and nobody gives
    (``const int x; // unused``); the float path accepts that, and so must this one.
    """
    defined: dict[str, bool] = {}
    for name in pending:
        todo: list[tuple[str, bool]] = [(name, False)]
        while todo:
            current, ready = todo.pop()
            if ready:
                own = pending[current].value is not None or current in given
                defined[current] = own and all(defined.get(n, False) for n in uses[current])
            elif current not in defined:
                defined[current] = False  # until known (and so for a cycle)
                todo.append((current, True))
                todo.extend((n, False) for n in reversed(uses[current]))
    return defined


def _constant(
    decl: ConstDecl, given: Mapping[str, Value | str], values: Mapping[str, ExactScalar]
) -> ExactScalar:
    if decl.value is None:
        result = _given(decl, given[decl.name])
    else:
        result = evaluate_rational(decl.value, values, {}, 1)[0]
    if decl.type == "bool":
        return bool(result)
    return mpz(result) if decl.type == "int" else mpq(result)


def _given(decl: ConstDecl, raw: Value | str) -> ExactScalar:
    """The exact value given for *decl*: a number as written (``0.1`` is 1/10), or
    a closed expression (``1/3``), as the float path accepted it."""
    if isinstance(raw, bool):
        return raw
    if not isinstance(raw, str):
        return rational(raw)
    text = raw.strip()
    if decl.type == "bool" and text in ("true", "false"):
        return text == "true"
    try:
        return rational(text)
    except (ValueError, ZeroDivisionError):
        return evaluate_rational(given_expression(decl, text), {}, {}, 1)[0]
