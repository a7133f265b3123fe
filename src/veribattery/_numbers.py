"""Exact numbers from what a user typed, their size checked before they are built.

``Fraction("1e99999999")`` computes 10^99999999 (minutes of CPU), and Python refuses to
write an int of more than 4,300 digits as text, so a message showing one became a
traceback. Every decimal a user types -- a config value, ``--set``, a ``--vary`` or
``--const`` range, a requirement's bound -- is read here: ``Decimal`` holds the written
exponent apart from the digits at no cost, so both are checked on the text first.

The bounds hold every double (down to the subnormal 5e-324) with room to spare, and
keep every product the model derives from a few such numbers short enough to show.
"""

from __future__ import annotations

import math
import numbers
import re
from decimal import Decimal, InvalidOperation
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fractions import Fraction

__all__ = ["MAX_DIGITS", "MAX_EXPONENT", "SIZE_RULE", "OutOfRange", "count_text",
           "exact_number", "nearest_float", "out_of_range", "shortened"]

#: The largest power of ten a number may reach, and the smallest it may go below 1.
MAX_EXPONENT = 400
#: The most significant digits a number (or either side of ``p/q``) may be written with.
MAX_DIGITS = 400
#: The rule, as messages state it.
SIZE_RULE = (f"a number must be 0 or between 1e-{MAX_EXPONENT} and 1e{MAX_EXPONENT} in "
             f"size, with at most {MAX_DIGITS} significant digits")
#: Text longer than this is shown cut in its middle.
_SHOWN = 24
_SMALLEST, _LARGEST = Decimal(f"1e-{MAX_EXPONENT}"), Decimal(f"1e{MAX_EXPONENT}")
#: A decimal with an exponent (Decimal refuses one beyond 10^18 digits' worth).
_SCIENTIFIC = re.compile(r"\s*[-+]?(?:\d[\d_]*\.?[\d_]*|\.\d[\d_]*)[eE][-+]?\d[\d_]*\s*")


class OutOfRange(ValueError):
    """A number written too large, too small or with too many digits (see :data:`SIZE_RULE`)."""


def exact_number(text: str) -> Fraction:
    """*text* as the exact rational :class:`~fractions.Fraction` reads (``0.3``,
    ``-2e-3``, ``1/3``), its size checked first.

    :raises OutOfRange: when it breaks :data:`SIZE_RULE` (the message quotes *text*).
    :raises ValueError: when *text* is not such a number (or divides by zero).
    """
    from fractions import Fraction  # (not imported by a check that reads no such number)

    numerator, slash, denominator = text.partition("/")
    if slash:
        if max(_digit_count(numerator), _digit_count(denominator)) > MAX_DIGITS:
            raise out_of_range(text)
        try:
            return Fraction(text)
        except ZeroDivisionError:
            raise ValueError(f"{text!r} divides by zero") from None
    number = _decimal(text)
    if number.is_zero():  # 0e99999999: Fraction would compute 10^99999999 to multiply by
        return Fraction(0)
    if not _SMALLEST <= number.copy_abs() <= _LARGEST or _significant(number) > MAX_DIGITS:
        raise out_of_range(text)
    return Fraction(number)


def count_text(count: int) -> str:
    """*count* with thousands separators, or ``about 10^N`` when it is long (a range's
    count of values can have hundreds of digits)."""
    if count < 10**15:
        return f"{count:,}"
    return f"about 10^{Decimal(count).adjusted()}"


def _decimal(text: str) -> Decimal:
    """*text* as a finite decimal, as Fraction's decimal form is written."""
    try:
        number = Decimal(text.strip())
    except InvalidOperation:
        if _SCIENTIFIC.fullmatch(text):
            raise out_of_range(text) from None
        raise ValueError(f"{shortened(text)!r} is not a number") from None
    if not number.is_finite():
        raise ValueError(f"{shortened(text)!r} is not a finite number")
    return number


def _significant(number: Decimal) -> int:
    """The digits of *number* from its first nonzero one to its last."""
    return len("".join(map(str, number.as_tuple().digits)).rstrip("0"))


def _digit_count(text: str) -> int:
    """The digits of one side of ``p/q`` (without its sign, underscores or leading zeros)."""
    return len(text.strip().lstrip("+-").replace("_", "").lstrip("0"))


def out_of_range(text: str) -> OutOfRange:
    """The error for the number written *text* (quoted cut in its middle when long)."""
    return OutOfRange(f"{shortened(text.strip())} is out of range: {SIZE_RULE}")


def shortened(text: str) -> str:
    """*text*, its middle cut when it is long (a number of 5,000 digits), to quote in a
    message."""
    if len(text) <= _SHOWN:
        return text
    return f"{text[:12]}…{text[-6:]} ({len(text):,} characters)"


def nearest_float(q: numbers.Rational) -> float:
    """The double nearest an exact rational (:class:`~fractions.Fraction` or ``mpq``);
    ``+inf`` or ``-inf`` beyond the largest double, where ``float()`` raises."""
    try:
        return float(q)
    except OverflowError:
        return math.inf if int(q.numerator) > 0 else -math.inf
