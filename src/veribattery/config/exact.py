"""Exact numbers from YAML: decimals as written, never binary floats.

A config's YAML floats keep the decimal they were written as
(:class:`~veribattery.config.source.WrittenFloat`: ``0.3`` → ``3/10``, and
``0.1000000000000000000001`` is not 0.1); a float from Python goes through ``repr``,
the shortest decimal that round-trips.
"""

from __future__ import annotations

import math
from decimal import Decimal
from fractions import Fraction
from typing import Annotated

from pydantic import BeforeValidator
from pydantic_core import PydanticCustomError

from veribattery._numbers import OutOfRange, exact_number
from veribattery.config.source import WrittenFloat

__all__ = ["Exact", "brief", "fraction_to_decimal", "problem", "show", "to_fraction"]

#: A value shown in a message is cut after about so many characters.
_BRIEF = 40


def problem(message: str, key: str = "", others: tuple[tuple[str, str], ...] = ()
            ) -> PydanticCustomError:
    """A validation error; *key* names a sub-key when raised by a model-level check.

    :param others: for a check across keys, the other sub-keys whose change would fix
        it too, each with the message that suits it: the error names the one the user
        gave (a ``--set`` before the file's), not a key the user never wrote.
    """
    return PydanticCustomError("vb_problem", "{message}",
                               {"message": message, "key": key, "others": others})


def show(value: object) -> str:
    """*value* as a user wrote it: decimals without binary noise, strings quoted."""
    if isinstance(value, Fraction):
        return _show_fraction(value)
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(show(v) for v in value) + "]"
    return str(value)


def brief(value: object) -> str:
    """*value* for a message: as :func:`show` writes it, but a long number in scientific
    notation and a long list cut (an alias can make a list of a million items)."""
    if isinstance(value, Fraction | int) and not isinstance(value, bool):
        return _brief_number(Fraction(value))
    if isinstance(value, tuple | list):
        return _brief_items(value)
    text = show(value)
    return text if len(text) <= _BRIEF else f"{text[:_BRIEF - 6]}…{text[-5:]}"


def _brief_number(value: Fraction) -> str:
    """Short enough: *value* as written; else ``1.23457e+400`` (never ``str`` of an int
    beyond Python's 4,300 digits)."""
    if max(value.numerator.bit_length(), value.denominator.bit_length()) < 3 * _BRIEF:
        text = show(value)
        if len(text) <= (20 if "." in text else _BRIEF):
            return text
        # A long decimal exactly, in the shorter of its two notations, where that is
        # short: rounded to six digits, 0.1000000000000000000001 would read as 0.100000.
        if "/" not in text:
            text = min(text, f"{Decimal(text).normalize():e}", key=len)
            if len(text) <= _BRIEF:
                return text
    return f"{(Decimal(value.numerator) / Decimal(value.denominator)).normalize():.6g}"


def _brief_items(items: tuple[object, ...] | list[object]) -> str:
    shown: list[str] = []
    for item in items:
        shown.append(brief(item))
        if sum(map(len, shown)) > _BRIEF:
            return "[" + ", ".join(shown) + f", … ({len(items):,} items)]"
    return "[" + ", ".join(shown) + "]"


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
    if isinstance(value, WrittenFloat):  # the decimal as written, not its nearest double
        return to_fraction(value.text)
    if isinstance(value, float) and math.isfinite(value):
        return Fraction(repr(value))
    if isinstance(value, str):
        try:
            return exact_number(value)
        except OutOfRange as exc:
            raise problem(str(exc)) from None
        except ValueError:
            pass
    raise problem(f"must be a number, got {brief(value)}")


#: A field holding an exact rational, from an int, float, decimal string or ``"p/q"``.
Exact = Annotated[Fraction, BeforeValidator(to_fraction)]
