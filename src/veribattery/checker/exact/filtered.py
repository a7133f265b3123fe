"""Exact results, and a top-level ``filter(...)`` answered in exact arithmetic.

Shared by the DTMC (:mod:`~veribattery.checker.exact.pctl`) and the MDP
(:mod:`~veribattery.checker.mdp.exact_pctl`) exact checkers: a filter reduces the exact
values of its operand over its states the same way on either.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from fractions import Fraction

import numpy as np
from gmpy2 import mpq

from veribattery._types import BoolArray, IntArray
from veribattery.checker.exact.numeric import ExactValues
from veribattery.checker.formula import filters
from veribattery.checker.result import CheckResult
from veribattery.lang.nodes import Expr, Filter, Property

__all__ = ["ExactCheckResult", "ExactModelView", "as_fraction", "filtered"]

_ZERO = mpq(0)


@dataclass(frozen=True, slots=True, repr=False)  # CheckResult's short repr
class ExactCheckResult(CheckResult):
    """A :class:`CheckResult` that also carries the exact answer.

    :param exact: the value at the first initial state as a :class:`fractions.Fraction`
        (None for booleans and infinite values).
    :param exact_values: per-state exact values (None for boolean results).
    """

    exact: Fraction | None = None
    exact_values: ExactValues | None = field(default=None, repr=False)  # per state, as values


def as_fraction(value: mpq) -> Fraction:
    """*value* as a :class:`fractions.Fraction`."""
    return Fraction(int(value.numerator), int(value.denominator))


@dataclass(frozen=True, slots=True)
class ExactModelView:
    """What a filter reads of an exact model (a DTMC's or an MDP's checker).

    :param values: a formula's exact values in every state (rationals or booleans).
    :param mask: the states satisfying a state formula.
    :param check: a whole property's exact result (a ``print`` filter's operand).
    :param states: the state table; :param names: its columns.
    :param initial: the initial states.
    """

    values: Callable[[Expr], ExactValues | BoolArray]
    mask: Callable[[Expr], BoolArray]
    check: Callable[[Property], ExactCheckResult]
    states: IntArray
    names: tuple[str, ...]
    initial: IntArray


def filtered(model: ExactModelView, prop: Property, node: Filter) -> ExactCheckResult:
    """A top-level ``filter(op, operand, states)``: the float outcome of its enclosure
    (:func:`~veribattery.checker.formula.filters.apply_filter`: listings, counts, booleans,
    which are exact), and for a number the exact value it picks or sums."""
    start = time.perf_counter()
    where = (np.ones(model.states.shape[0], dtype=bool) if node.states is None
             else model.mask(node.states))
    inner = model.values(node.operand)
    per_state = inner.enclosure() if isinstance(inner, ExactValues) else inner
    outcome = filters.apply_filter(node.op, per_state, where, model.states, model.names,
                                   node.span)
    if outcome.value is None and node.op.startswith("arg"):  # the listed states, as a set
        mask = np.asarray(outcome.values, dtype=bool)
        plain = CheckResult.at_initial(prop, mask, model.initial, time.perf_counter() - start)
        return ExactCheckResult(prop, plain.values, plain.value, plain.time_s,
                                printed=outcome.printed)
    if outcome.value is None:  # print, printall: the listing, and the operand's answer
        answer = model.check(replace(prop, formula=node.operand))
        return replace(answer, property=prop, printed=outcome.printed)
    plain = CheckResult.of_answer(prop, outcome, time.perf_counter() - start)
    if not isinstance(inner, ExactValues) or node.op not in _EXACT_FILTERS:
        return ExactCheckResult(prop, plain.values, plain.value, plain.time_s, plain.lower,
                                plain.upper, plain.precise, plain.bounds, plain.value_range,
                                plain.printed)
    value, infinite = _filter_exact(node.op, inner, where, model.states)
    return ExactCheckResult(
        prop, plain.values, plain.value, plain.time_s, plain.lower, plain.upper,
        plain.precise, plain.bounds, plain.value_range, plain.printed,
        exact=None if infinite else as_fraction(value), exact_values=inner)


#: The filters whose number is picked or summed exactly (``range``: its lowest value).
_EXACT_FILTERS = frozenset({"state", "first", "min", "max", "range", "sum", "avg"})


def _filter_exact(op: str, inner: ExactValues, where: BoolArray,
                  states: IntArray) -> tuple[mpq, bool]:
    """The exact number of a numeric filter over *where*, and whether it is infinite."""
    picked = np.flatnonzero(where)
    if op in ("sum", "avg"):
        if inner.infinite[picked].any():
            return _ZERO, True
        total = sum(inner.values[picked], _ZERO)
        return (total if op == "sum" else total / picked.size), False
    if op == "first":
        order = filters.state_order(states)
        picked = order[where[order]][:1]
    ranked = sorted(picked, key=lambda s: (bool(inner.infinite[s]), inner.values[s]))
    state = ranked[-1] if op == "max" else ranked[0]
    return inner.values[state], bool(inner.infinite[state])
