"""PRISM's experiments: a constant given a range, ``--const N=2:5`` or ``p=0.1:0.1:0.5``
(``start:end`` or ``start:step:end``, both ends included), checked at every value, and
several ranges at every combination (the first constant varies slowest)."""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from decimal import Decimal
from fractions import Fraction

from veribattery._numbers import OutOfRange, count_text, exact_number
from veribattery.errors import PrismSemanticError

__all__ = ["MAX_POINTS", "constant_points", "is_range"]

#: The most points an experiment may have.
MAX_POINTS = 10_000


def is_range(value: str) -> bool:
    """Whether a ``--const`` value is a range (``a:b`` or ``a:step:b``)."""
    return ":" in value


def constant_points(given: Mapping[str, str]) -> list[dict[str, str]]:
    """Every assignment of *given*'s constants: ranges expanded, the others as they are.

    :raises PrismSemanticError: for a range that is not numbers, has a zero step, runs
        away from its end, or a grid of more than :data:`MAX_POINTS` points.
    """
    axes = [[(name, value)] if not is_range(value) else
            [(name, point) for point in _range_values(name, value)]
            for name, value in given.items()]
    count = 1
    for axis in axes:
        count *= len(axis)
    if count > MAX_POINTS:
        raise PrismSemanticError(f"--const ranges make {count_text(count)} points; at most "
                                 f"{MAX_POINTS:,} are checked: narrow a range or widen a step")
    return [dict(point) for point in itertools.product(*axes)]


def _range_values(name: str, value: str) -> list[str]:
    """The values of ``start:end`` or ``start:step:end``, written exactly."""
    parts = value.split(":")
    try:
        numbers = [exact_number(part) for part in parts]
    except OutOfRange as exc:
        raise PrismSemanticError(f"--const {name}={value}: {exc}") from None
    except ValueError:
        numbers = []
    if len(parts) not in (2, 3) or len(numbers) != len(parts):
        raise PrismSemanticError(
            f"--const {name}={value}: a range is start:end or start:step:end of numbers, "
            "e.g. N=2:5 or p=0.1:0.1:0.5")
    start, step, end = (numbers[0], Fraction(1), numbers[1]) if len(numbers) == 2 else numbers
    if step == 0 or (end - start) * step < 0:
        raise PrismSemanticError(
            f"--const {name}={value}: the step {_written(step)} never reaches "
            f"{_written(end)} from {_written(start)}")
    count = int((end - start) / step) + 1
    if count > MAX_POINTS:
        raise PrismSemanticError(f"--const {name}={value} has {count_text(count)} values; at most "
                                 f"{MAX_POINTS:,} are checked")
    return [_written(start + i * step) for i in range(count)]


def _written(value: Fraction) -> str:
    """*value* as --const takes it: an integer, a decimal when it has one, else p/q."""
    if value.denominator == 1:
        return str(value.numerator)
    decimal = Decimal(value.numerator) / Decimal(value.denominator)
    if Fraction(decimal) == value:
        return format(decimal.normalize(), "f")
    return f"{value.numerator}/{value.denominator}"
