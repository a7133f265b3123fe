"""Exact numbers from YAML: decimals as written, never binary floats.

YAML hands us binary floats; ``Fraction(repr(x))`` recovers the decimal the user wrote
(``0.3`` → ``3/10``), because ``repr`` gives the shortest decimal that round-trips.
"""

from __future__ import annotations

import math
from decimal import Decimal
from fractions import Fraction
from typing import Annotated

from pydantic import BeforeValidator
from pydantic_core import PydanticCustomError

__all__ = ["Exact", "fraction_to_decimal", "problem", "show", "to_fraction"]


def problem(message: str, key: str = "") -> PydanticCustomError:
    """A validation error; *key* names a sub-key when raised by a model-level check."""
    return PydanticCustomError("vb_problem", "{message}", {"message": message, "key": key})


def show(value: object) -> str:
    """*value* as a user wrote it: decimals without binary noise, strings quoted."""
    if isinstance(value, Fraction):
        return _show_fraction(value)
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(show(v) for v in value) + "]"
    return str(value)


def _show_fraction(value: Fraction) -> str:
    if value.denominator == 1:
        return str(value.numerator)
    decimal = fraction_to_decimal(value)
    return str(value) if decimal is None else decimal


def fraction_to_decimal(value: Fraction) -> str | None:
    """The exact decimal text of *value*, or ``None`` when it does not terminate."""
    den = value.denominator
    twos = fives = 0
    while den % 2 == 0:
        den, twos = den // 2, twos + 1
    while den % 5 == 0:
        den, fives = den // 5, fives + 1
    if den != 1:
        return None
    places = max(twos, fives, 1)
    text = f"{Decimal(value.numerator) / Decimal(value.denominator):.{places}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def to_fraction(value: object) -> Fraction:
    """Exact rational from a YAML scalar; floats go through ``repr`` to undo binary rounding."""
    if isinstance(value, Fraction):
        return value
    if isinstance(value, bool):
        raise problem(f"must be a number, got {value}")
    if isinstance(value, int | Decimal):
        return Fraction(value)
    if isinstance(value, float) and math.isfinite(value):
        return Fraction(repr(value))
    if isinstance(value, str):
        try:
            return Fraction(value.strip())
        except (ValueError, ZeroDivisionError):
            pass
    raise problem(f"must be a number, got {show(value)}")


#: A field holding an exact rational, from an int, float, decimal string or ``"p/q"``.
Exact = Annotated[Fraction, BeforeValidator(to_fraction)]
