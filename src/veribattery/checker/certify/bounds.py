"""Certified per-state results: a point value inside an interval that provably holds the truth.

Every numeric kernel returns :class:`Bounds`. ``lower <= exact <= upper`` holds for
the exact value of the model as built (its float64 transition matrix and rewards
taken as exact numbers); ``docs/numerics.md`` gives the argument for each kernel.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass

import numpy as np

from veribattery._numbers import nearest_float
from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.lang.nodes import BOUND_RELATIONS

#: Default precision: an interval is *precise* when its width is at most this,
#: relative to the value ...
RELATIVE_PRECISION = 1e-9
#: ... or at most this in absolute terms.
ABSOLUTE_PRECISION = 1e-12

_PRECISION: ContextVar[tuple[float, float]] = ContextVar(
    "precision", default=(RELATIVE_PRECISION, ABSOLUTE_PRECISION))


@contextmanager
def required_precision(relative: float, absolute: float) -> Iterator[None]:
    """Kernels called inside escalate until intervals are this narrow (0, 0: exact)."""
    token = _PRECISION.set((relative, absolute))
    try:
        yield
    finally:
        _PRECISION.reset(token)


def current_precision() -> tuple[float, float]:
    """The (relative, absolute) width kernels are asked for now (see :func:`required_precision`)."""
    return _PRECISION.get()


def round_down(x: FloatArray) -> FloatArray:
    """The next float below each entry (covers one rounding to nearest)."""
    return np.nextafter(x, -np.inf)


def round_up(x: FloatArray) -> FloatArray:
    """The next float above each entry (covers one rounding to nearest)."""
    return np.nextafter(x, np.inf)


def rational_bounds(values: Iterable[numbers.Rational]) -> Bounds:
    """Exact rationals as certified floats: the nearest double (:func:`nearest_float`),
    inside the doubles either side unless it is the value itself. A value beyond the
    largest double is ``inf`` in ``[largest double, inf]`` (its sign mirrored)."""
    from fractions import Fraction  # only after an exact solve (a small check needs none)

    exact = list(values)
    value = np.array([nearest_float(q) for q in exact], dtype=np.float64)
    above = np.array([f > q if math.isinf(f) else Fraction(f) > q
                      for f, q in zip(value.tolist(), exact, strict=True)], dtype=bool)
    below = np.array([f < q if math.isinf(f) else Fraction(f) < q
                      for f, q in zip(value.tolist(), exact, strict=True)], dtype=bool)
    with np.errstate(over="ignore"):  # (the largest double's neighbour, where unused)
        return Bounds(value, np.where(above, round_down(value), value),
                      np.where(below, round_up(value), value))


@dataclass(frozen=True, slots=True)
class Bounds:
    """Per-state point values with certified enclosures ``lower <= exact <= upper``.

    :param value: the best float64 estimate of each state's value (inside the interval).
    :param lower: certified lower bounds.
    :param upper: certified upper bounds.
    """

    value: FloatArray
    lower: FloatArray
    upper: FloatArray

    @classmethod
    def exact(cls, value: FloatArray) -> Bounds:
        """Values known exactly (0/1 from graph analysis, infinities, exact sums)."""
        return cls(value, value.copy(), value.copy())

    def at(self, index: IntArray) -> Bounds:
        """The bounds of the states *index* only."""
        return Bounds(self.value[index], self.lower[index], self.upper[index])

    @classmethod
    def around(cls, value: FloatArray, lower: FloatArray, upper: FloatArray) -> Bounds:
        """Bounds whose point value is *value* moved into ``[lower, upper]``."""
        return cls(np.minimum(np.maximum(value, lower), upper), lower, upper)

    @classmethod
    def uncertified(cls, value: FloatArray, lowest: float, highest: float) -> Bounds:
        """Values with no computed error bound: only the quantity's own range encloses them.

        Used by operators whose results are not certified yet (Storm's conditional and
        reward-bounded formulas): a probability in [0, 1], a reward in [0, inf]. The
        interval is true but wide, so such results are reported as imprecise.
        """
        undefined = np.isnan(value)  # no value at all (a condition impossible there)
        lower = np.where(undefined, value, lowest)
        upper = np.where(undefined, value, highest)
        return cls(value, lower, upper)

    def within(self, lowest: float, highest: float) -> Bounds:
        """These bounds met with ``[lowest, highest]``, a range the exact values are known
        to lie in by other means (``I=k``: :func:`horizon.power_range`)."""
        if not (np.isfinite(lowest) and np.isfinite(highest)):
            return self
        lower = np.clip(self.lower, lowest, highest)
        upper = np.clip(self.upper, lowest, highest)
        return Bounds.around(self.value, lower, upper)

    @property
    def width(self) -> FloatArray:
        """``upper - lower`` (0 where both are the same infinity)."""
        same = self.lower == self.upper
        with np.errstate(invalid="ignore"):
            return np.where(same, 0.0, self.upper - self.lower)

    def precise_states(self, relative: float | None = None,
                       absolute: float | None = None) -> BoolArray:
        """States whose interval meets the precision (relative *or* absolute).

        An infinite value is precise only as the interval of that infinity itself: one
        that starts at a finite bound (a value beyond the largest double) is not.
        Unset arguments come from :func:`required_precision` (default 1e-9, 1e-12).
        """
        default_relative, default_absolute = _PRECISION.get()
        relative = default_relative if relative is None else relative
        absolute = default_absolute if absolute is None else absolute
        magnitude = np.abs(self.value)
        allowed = np.maximum(relative * np.where(np.isinf(magnitude), 0.0, magnitude), absolute)
        return np.asarray(self.width <= allowed, dtype=np.bool_)

    def complement(self) -> Bounds:
        """``1 - x`` with outward rounding (``G phi`` from ``F !phi``), kept in [0, 1]: a
        probability's bounds (an upper bound a little above 1, of rows stored a little
        above 1, would give a lower bound below 0)."""
        lower = np.maximum(_one_minus(self.upper, round_down), 0.0)
        upper = np.minimum(_one_minus(self.lower, round_up), 1.0)
        return Bounds.around(1.0 - self.value, lower, upper)

    def compare(self, op: str, threshold: float) -> tuple[BoolArray, BoolArray]:
        """``value op threshold`` decided from the interval.

        :return: ``(holds, undecided)``: *holds* where the comparison is true for
            every number in the interval, *undecided* where it is true for some only.
        """
        compare = BOUND_RELATIONS[op]
        at_lower, at_upper = compare(self.lower, threshold), compare(self.upper, threshold)
        return at_lower & at_upper, at_lower != at_upper


def _one_minus(x: FloatArray, direction: Callable[[FloatArray], FloatArray]) -> FloatArray:
    """``1 - x`` rounded in *direction* only where the subtraction was inexact.

    Knuth's TwoSum recovers the exact rounding error of ``fl(1 - x)``.
    """
    with np.errstate(invalid="ignore"):
        y = 1.0 - x
        back = y - 1.0
        error = (1.0 - (y - back)) + (-x - back)
    return np.where((error == 0) | ~np.isfinite(y), y, direction(y))


def escalated() -> bool:
    """Whether kernels are already asked for exact bounds (no retry would help)."""
    return _PRECISION.get() == (0.0, 0.0)
