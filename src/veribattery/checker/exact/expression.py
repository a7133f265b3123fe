"""State expressions over exact values, evaluated in rationals in every state.

``round(1 + P=? [ F<=1 d=6 ])``, ``(2*"one")^(d+3)``, ``s+1``, ``Pmax=? [ F a ] >= 1/3``:
in ``--exact`` mode, as PRISM's exact engine, each is evaluated exactly in every state.
The operators inside (``P``, ``R``, ``S``, ``A``/``E``, filters) are answered by the
checker (the DTMC's or the MDP's) and enter as variables of the expression; labels and
the model's variables too; a closed number keeps the exact value it has as written
(:mod:`~veribattery.explore.exact.decided` writes it as the literal's text). The rest is
:func:`~veribattery.explore.exact.rational.evaluate_rational`: PRISM's operators and
functions in rationals, each evaluated once over all states.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from gmpy2 import mpq

from veribattery._types import BoolArray, IntArray
from veribattery.checker.exact.numeric import ExactValues
from veribattery.checker.formula.leaves import has_operator
from veribattery.errors import CheckError, ModelError, Span
from veribattery.explore.exact.program import needs_exact
from veribattery.explore.exact.rational import evaluate_rational
from veribattery.explore.exact.rational_ops import as_objects
from veribattery.lang.expressions import substitute, walk
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Expr,
    Filter,
    Ident,
    LabelRef,
    ProbOp,
    Quantified,
    RewardOp,
    SteadyOp,
)

__all__ = ["ExactStates", "exact_expression", "exact_state_values"]

#: The nodes the checker answers: they enter an expression as its variables.
_OPERATORS = (ProbOp, RewardOp, SteadyOp, Quantified, Filter)


@dataclass(frozen=True, slots=True)
class ExactStates:
    """What an expression reads of a model's states.

    :param states: the state table (one row per state); :param names: its columns.
    :param labels: the model's labels as state masks.
    """

    states: IntArray
    names: tuple[str, ...]
    labels: Mapping[str, BoolArray]


def exact_state_values(expr: Expr, at: ExactStates,
                       operand: Callable[[Expr], ExactValues | BoolArray],
                       leaf: Callable[[Expr], np.ndarray]) -> ExactValues | BoolArray:
    """:func:`exact_expression`, except for an operator-free *expr* that doubles
    evaluate exactly (no double, division, ``pow`` or ``log`` in it): *leaf* evaluates it
    (the checker's compiled evaluator, in doubles). A predicate that has no exact
    value (``floor(log(d+1, 2)) = 2``) is decided in doubles too, as documented; a
    number without one is a :class:`ModelError`.

    :param leaf: an operator-free expression's values in every state, in doubles.
    """
    if has_operator(expr):
        return exact_expression(expr, at, operand)
    if not needs_exact(expr):
        values = leaf(expr)
        if values.dtype == np.bool_:
            return np.asarray(values, dtype=np.bool_)
        if np.all(values == np.round(values)):  # integers: exact in doubles below 2^53
            return ExactValues.finite(as_objects([mpq(int(v)) for v in values]))
    try:
        return exact_expression(expr, at, operand)
    except ModelError:
        values = leaf(expr)
        if values.dtype == np.bool_:
            return np.asarray(values, dtype=np.bool_)
        raise


def exact_expression(expr: Expr, at: ExactStates,
                     operand: Callable[[Expr], ExactValues | BoolArray]) -> ExactValues | BoolArray:
    """*expr*'s exact value in every state: rationals, or booleans for a state formula.

    :param operand: an operator's exact values (``P=?`` ...) or states (``P>p`` ...).
    :raises CheckError: for an infinite operand (no arithmetic on it here).
    :raises ModelError: for an operation without an exact rational value (``log``, a
        fractional power).
    """
    variables: dict[str, np.ndarray] = {}
    doubles: set[str] = set()

    def replace(node: Any) -> Any | None:
        if isinstance(node, _OPERATORS):
            name = f"\0{len(variables)}"
            variables[name] = _operand_values(operand(node), node.span)
            if variables[name].dtype != bool:
                doubles.add(name)
            return Ident(name, node.span)
        if isinstance(node, LabelRef):
            name = f"\0label {node.name}"
            variables[name] = np.asarray(at.labels[node.name], dtype=bool)
            return Ident(name, node.span)
        return None

    rewritten = substitute(expr, replace)
    bools = _bool_variables(rewritten)
    for node in walk(rewritten):
        if isinstance(node, Ident) and node.name in at.names and node.name not in variables:
            column = at.states[:, at.names.index(node.name)]
            variables[node.name] = (column.astype(bool) if node.name in bools
                                    else as_objects([mpq(int(v)) for v in column]))
    result = evaluate_rational(rewritten, {}, variables, at.states.shape[0], doubles=doubles)
    if result.dtype == bool:
        return np.asarray(result, dtype=bool)
    return ExactValues.finite(np.asarray(result, dtype=object))


def _operand_values(found: ExactValues | BoolArray, span: Span | None) -> np.ndarray:
    if not isinstance(found, ExactValues):
        return np.asarray(found, dtype=bool)
    if found.infinite.any():
        raise CheckError("an infinite expected reward has no exact arithmetic here", span)
    return np.asarray(found.values, dtype=object)


def _bool_variables(expr: Expr) -> set[str]:
    """The variables read as booleans: resolution writes a boolean variable ``b`` as
    ``b=true`` (the state table holds it as 0/1)."""
    return {node.left.name for node in walk(expr)
            if isinstance(node, Binary) and node.op == "=" and isinstance(node.left, Ident)
            and node.right == BoolLit(True)}
