"""PRISM's filters: ``filter(op, prop, states)`` reduces per-state values to one answer.

Operators on arrays only (the formula recursion is in :mod:`~veribattery.checker.formula.pctl`).
"First" and the printed state lists use PRISM's state order: lexicographic in
the variables' values, in declaration order.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.certify.bounds import (
    ABSOLUTE_PRECISION,
    RELATIVE_PRECISION,
    Bounds,
)
from veribattery.errors import CheckError, Span

Values = FloatArray | BoolArray
#: Per-state input: certified numbers, or booleans.
Result = Bounds | BoolArray
Scalar = float | bool | int

#: Filters whose result is one value (the others give a value per state).
SINGLE_VALUED = frozenset({
    "min", "max", "count", "sum", "avg", "first", "range", "forall", "exists", "state",
})


@dataclass(frozen=True, slots=True)
class FilterOutcome:
    """A filter's result: *value* for single-valued filters (a ``(low, high)`` pair
    for ``range``), otherwise *values* per state; *printed* holds the lines of
    ``print``, ``printall``, ``argmin`` and ``argmax``; *interval* encloses a
    numeric *value* (for ``range`` the whole range) with certified bounds, and
    *precise* says whether it meets the default precision (for ``range``: every
    state's interval does). *certified* is False for an answer computed in floating
    point without a certificate (a multi-objective linear programme): its *interval*
    is then an error estimate, not a bound."""

    value: Scalar | tuple[float, float] | None
    values: Bounds | Values
    printed: tuple[str, ...] = field(default=())
    interval: tuple[float, float] | None = None
    precise: bool = True
    certified: bool = True


def state_order(states: IntArray) -> IntArray:
    """State indices in PRISM's order (lexicographic in the variable values)."""
    if states.shape[1] == 0:
        return np.arange(states.shape[0])
    return np.lexsort(states.T[::-1])


def _scalar(value: np.generic | float | bool) -> Scalar:
    if isinstance(value, np.bool_ | bool):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    return float(value)


def _describe(row: IntArray, names: tuple[str, ...]) -> str:
    return "(" + ",".join(f"{n}={int(v)}" for n, v in zip(names, row, strict=True)) + ")"


def apply_filter(op: str, values: Result, where: BoolArray, states: IntArray,
                 names: tuple[str, ...], span: Span | None = None) -> FilterOutcome:
    """Apply the filter operator *op* to *values* over the states in *where*.

    :param op: a PRISM filter operator (``min``, ``forall``, ``print`` ...).
    :param values: the property's value in every state.
    :param where: the filter's states.
    :param states: the state table (for ``first`` and printing).
    :param names: the variable names (for printing).
    :raises CheckError: when *where* is empty, or ``state`` is not exactly one state.
    """
    if not where.any():
        raise CheckError(f"the states of filter({op}, ...) are empty", span)
    point = values.value if isinstance(values, Bounds) else values
    if op in ("print", "printall", "argmin", "argmax"):
        outcome = _listing(op, point, where, states, names)
        return outcome if op.startswith("arg") else replace(outcome, values=values)
    outcome = _reduce(op, point, where, states, span)
    if not isinstance(values, Bounds) or op not in _NUMERIC:
        return outcome
    low, high = _enclosure(op, values, where, states)
    if op == "range":
        precise = bool(values.precise_states(RELATIVE_PRECISION, ABSOLUTE_PRECISION)[where].all())
    else:
        assert isinstance(outcome.value, float | int)
        ends = Bounds(np.array([float(outcome.value)]), np.array([low]), np.array([high]))
        precise = bool(ends.precise_states(RELATIVE_PRECISION, ABSOLUTE_PRECISION)[0])
    return replace(outcome, values=values, interval=(low, high), precise=precise)


def _reduce(op: str, values: Values, where: BoolArray, states: IntArray,
            span: Span | None) -> FilterOutcome:
    """The single-valued filters on point values."""
    picked = values[where]
    if op == "state" and picked.size != 1:
        raise CheckError(f"filter(state, ...) needs exactly one state, but {picked.size} "
                         "states satisfy the filter", span)
    if op == "first":
        order = state_order(states)
        first = order[where[order]][0]
        return FilterOutcome(_scalar(values[first]), values)
    if op == "range":
        return FilterOutcome((float(picked.min()), float(picked.max())), values)
    reducers: dict[str, Any] = {
        "min": np.min, "max": np.max, "sum": np.sum, "avg": np.mean, "state": np.min,
        "forall": np.all, "exists": np.any, "count": np.count_nonzero,
    }
    return FilterOutcome(_scalar(reducers[op](picked)), values)


#: Filters whose value is a number computed from the numbers filtered.
_NUMERIC = frozenset({"min", "max", "range", "first", "state", "sum", "avg"})


def _enclosure(op: str, values: Bounds, where: BoolArray,
               states: IntArray) -> tuple[float, float]:
    """Certified bounds of a numeric filter's value from the per-state bounds.

    ``min``/``max``/``range`` are monotone (exact on the ends); ``sum``/``avg`` add
    the ends with the rounding error of a float sum bounded and added outward.
    """
    lower, upper = values.lower[where], values.upper[where]
    if op in ("min", "state"):
        return float(lower.min()), float(upper.min())
    if op == "max":
        return float(lower.max()), float(upper.max())
    if op == "range":
        return float(lower.min()), float(upper.max())
    if op == "first":
        order = state_order(states)
        first = order[where[order]][0]
        return float(values.lower[first]), float(values.upper[first])
    low, high = _sum_down(lower), -_sum_down(-upper)
    if op == "avg":
        count = float(lower.size)
        return float(np.nextafter(low / count, -np.inf)), float(np.nextafter(high / count, np.inf))
    return low, high


def _sum_down(x: FloatArray) -> float:
    """A float below the exact sum of *x*.

    A float sum of *n* terms errs by at most ``(n-1) u sum|x|`` (Higham, 4.2);
    the bound is doubled to cover its own rounding.
    """
    with np.errstate(invalid="ignore", over="ignore"):
        total = float(np.sum(x))
        if not np.isfinite(total):
            return -np.inf if np.isnan(total) else total
        error = 2.0 * x.size * 2.0**-53 * float(np.sum(np.abs(x)))
        return float(np.nextafter(total - error, -np.inf))


def _listing(op: str, values: Values, where: BoolArray, states: IntArray,
             names: tuple[str, ...]) -> FilterOutcome:
    """``print``/``printall`` (values kept) and ``argmin``/``argmax`` (a state set)."""
    result: Values = values
    shown: BoolArray = where.copy()
    if op in ("argmin", "argmax"):
        extreme = values[where].min() if op == "argmin" else values[where].max()
        shown = np.asarray(where & (values == extreme))
        result = shown
    elif op == "print":
        shown = where & (values != 0)
    order = state_order(states)
    chosen = order[shown[order]]
    lines = tuple(
        f"{i}:{_describe(states[i], names)}" + ("" if op.startswith("arg") else
                                               f"={_format(values[i])}")
        for i in chosen
    )
    return FilterOutcome(None, result, lines)


def _format(value: np.generic) -> str:
    scalar = _scalar(value)
    if isinstance(scalar, bool):
        return "true" if scalar else "false"
    return repr(scalar) if isinstance(scalar, int) else f"{scalar:.12g}"
