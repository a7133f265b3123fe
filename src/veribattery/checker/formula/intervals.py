"""Properties as expressions, certified: interval arithmetic over :class:`Bounds`.

``1 - P=? [..]``, ``P=? [..] + P=? [..]``, ``min(R=? [..], 3)``: the point values
are computed by :mod:`~veribattery.checker.formula.expression` (PRISM's types and
rules); the certified enclosure alongside, rounded outward. Where no enclosure
is derived (``pow``, ``log``, ``mod`` of inexact numbers, ``0 * inf``), the
interval is ``[-inf, inf]``: honest, and reported as imprecise. Comparisons of
numbers are decided from the intervals, with one exact-precision retry, and
refused when still undecided (as bounded operators are).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

from veribattery._types import BoolArray, FloatArray
from veribattery.checker.certify.bounds import Bounds, round_down, round_up
from veribattery.checker.formula import expression
from veribattery.errors import CheckError, Span
from veribattery.explore.compile import arrays
from veribattery.lang.nodes import BOUND_RELATIONS

Result: TypeAlias = Bounds | BoolArray
Values = npt.NDArray[Any]


class Undecided(CheckError):
    """A comparison of numbers whose intervals overlap in some state, or a ``P~p``/``R~r``
    bound that a state's certified interval straddles (at exact precision too)."""

    @classmethod
    def straddled(cls, relation: str, threshold: float, numbers: Bounds,
                  undecided: BoolArray, span: Span | None) -> Undecided:
        """The bound ``relation threshold`` that the intervals of the *undecided* states
        straddle, naming the first of them and its interval."""
        state = int(np.flatnonzero(undecided)[0])
        low, high = float(numbers.lower[state]), float(numbers.upper[state])
        return cls(f"precision not enough to decide {relation} {threshold:g}: in "
                   f"{int(undecided.sum())} state(s) the certified interval straddles the "
                   f"bound (state {state}: [{low!r}, {high!r}])", span)


def _point(result: Result) -> Values:
    return result.value if isinstance(result, Bounds) else result


def _bounds(result: Result) -> Bounds:
    """A numeric result as bounds (a mask here is a type error caught by expression)."""
    if isinstance(result, Bounds):
        return result
    return Bounds.exact(np.asarray(result, dtype=np.float64))


def _unknown(value: Values) -> Bounds:
    """*value* with no certified enclosure (``[-inf, inf]``)."""
    shape = np.shape(value)
    return Bounds(value, np.full(shape, -np.inf), np.full(shape, np.inf))


def unary(op: str, operand: Result, span: Span | None = None) -> Result:
    """``!a`` or ``-a`` state by state (negation is exact)."""
    value = expression.unary(op, _point(operand), span)
    if op == "!":
        return np.asarray(value, dtype=np.bool_)
    ends = _bounds(operand)
    return Bounds(value, -ends.upper, -ends.lower)


def _sum(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``a + b`` rounded down and up (TwoSum finds the exact rounding error). A sum of
    finite numbers that overflows is beyond the largest double, not infinite."""
    with np.errstate(invalid="ignore", over="ignore"):
        s = a + b
        back = s - a
        error = (a - (s - back)) + (b - back)
    finite = np.isfinite(s) & np.isfinite(error)
    overflow = np.isinf(s) & np.isfinite(a) & np.isfinite(b)
    low = np.where((finite & (error < 0)) | (overflow & (s > 0)), round_down(s), s)
    high = np.where((finite & (error > 0)) | (overflow & (s < 0)), round_up(s), s)
    return low, high


def _corners(op: Callable[[FloatArray, FloatArray], FloatArray], a: Bounds,
             b: Bounds) -> tuple[FloatArray, FloatArray]:
    """Outward-rounded min and max of *op* over the interval corners (NaN: unbounded)."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        corners = np.stack([op(x, y) for x in (a.lower, a.upper) for y in (b.lower, b.upper)])
    nan = np.isnan(corners).any(axis=0)
    low = np.where(nan, -np.inf, round_down(np.nanmin(np.where(np.isnan(corners), 0, corners),
                                                      axis=0)))
    high = np.where(nan, np.inf, round_up(np.nanmax(np.where(np.isnan(corners), 0, corners),
                                                    axis=0)))
    return low, high


def _arithmetic(op: str, a: Bounds, b: Bounds) -> tuple[FloatArray, FloatArray]:
    if op == "+":
        low, _ = _sum(a.lower, b.lower)
        return low, _sum(a.upper, b.upper)[1]
    if op == "-":
        low, _ = _sum(a.lower, -b.upper)
        return low, _sum(a.upper, -b.lower)[1]
    if op == "*":
        return _corners(np.multiply, a, b)
    low, high = _corners(np.true_divide, a, b)
    straddles = (b.lower <= 0) & (b.upper >= 0)
    return np.where(straddles, -np.inf, low), np.where(straddles, np.inf, high)


def binary(op: str, left: Result, right: Result, span: Span | None = None) -> Result:
    """``left op right`` state by state, with certified bounds for numbers."""
    value = expression.binary(op, _point(left), _point(right), span)
    if value.dtype == np.bool_:
        if isinstance(left, Bounds) or isinstance(right, Bounds):
            return _compare(op, _bounds(left), _bounds(right), value, span)
        return np.asarray(value, dtype=np.bool_)
    low, high = _arithmetic(op, _bounds(left), _bounds(right))
    return Bounds(value, low, high)


def _compare(op: str, a: Bounds, b: Bounds, value: Values, span: Span | None) -> BoolArray:
    """A comparison of numbers decided from their intervals (refused where they overlap)."""
    if op in BOUND_RELATIONS:
        holds = BOUND_RELATIONS[op](a.lower, b.upper) & BOUND_RELATIONS[op](a.upper, b.lower)
        fails = ~BOUND_RELATIONS[op](a.upper, b.lower) & ~BOUND_RELATIONS[op](a.lower, b.upper)
    else:
        point = (a.lower == a.upper) & (b.lower == b.upper) & (a.lower == b.lower)
        apart = (a.upper < b.lower) | (b.upper < a.lower)
        holds, fails = (point, apart) if op == "=" else (apart, point)
    undecided = ~holds & ~fails
    if undecided.any():
        state = int(np.flatnonzero(undecided)[0])
        raise Undecided(
            f"precision not enough to decide '{op}': in {int(undecided.sum())} state(s) "
            f"the certified intervals overlap (state {state}: [{a.lower[state]!r}, "
            f"{a.upper[state]!r}] {op} [{b.lower[state]!r}, {b.upper[state]!r}])", span)
    return np.asarray(holds, dtype=np.bool_)


def choose(cond: BoolArray, then: Result, otherwise: Result) -> Result:
    """``cond ? then : otherwise`` state by state."""
    value = expression.choose(cond, _point(then), _point(otherwise))
    if value.dtype == np.bool_:
        return np.asarray(value, dtype=np.bool_)
    a, b = _bounds(then), _bounds(otherwise)
    return Bounds(value, np.where(cond, a.lower, b.lower), np.where(cond, a.upper, b.upper))


def _monotone(fn: Callable[[FloatArray], FloatArray], value: Values, a: Bounds) -> Bounds:
    """A non-decreasing exact function (floor, ceil, round, in doubles) maps the ends."""
    with np.errstate(invalid="ignore"):
        return Bounds(value, fn(a.lower), fn(a.upper))


def call(func: str, args: Sequence[Result], span: Span | None = None) -> Result:
    """A PRISM built-in function state by state, with certified bounds where derived."""
    value = expression.call(func, [_point(a) for a in args], span)
    if value.dtype == np.bool_:
        return np.asarray(value, dtype=np.bool_)
    ends = [_bounds(a) for a in args]
    if func in ("min", "max"):
        reduce = np.minimum.reduce if func == "min" else np.maximum.reduce
        return Bounds(value, reduce([e.lower for e in ends]), reduce([e.upper for e in ends]))
    if func in ("floor", "ceil", "round"):
        rounders: dict[str, Callable[[FloatArray], FloatArray]] = {
            "floor": np.floor, "ceil": np.ceil, "round": arrays.rounded_half_up}
        return _monotone(rounders[func], value, ends[0])
    if all(bool(np.all(e.lower == e.upper)) for e in ends) and np.issubdtype(value.dtype,
                                                                             np.integer):
        return Bounds.exact(value)  # pow/mod of exact ints is exact
    return _unknown(value)

