"""PRISM's operators in exact rationals: the rational domain of :mod:`veribattery.lang.ops`.

Numbers are numpy object arrays of :class:`gmpy2.mpq` (ints and doubles alike: the
evaluator knows each operand's PRISM type), booleans numpy bool arrays. Each
function gives, element by element, the exact value of the reference semantics, or
raises :class:`~veribattery.lang.ops.OperatorError` where there is none: where the
reference gives an infinity or a NaN (``x/0``, ``pow(0, -1.0)``), an irrational
number (``log``, ``pow`` with a fractional exponent), or an error (``mod(x, 0)``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from gmpy2 import mpq

from veribattery.lang.ops import (
    INT_MAX,
    INT_MIN,
    MOD_DIVISOR,
    MOD_INTEGERS,
    NEGATIVE_EXPONENT,
    POW_OVERFLOW,
    OperatorError,
)

__all__ = ["BINARY", "FUNCTIONS", "as_objects", "bools", "power"]

ZERO = mpq(0)
HALF = mpq(1, 2)

#: Why a function has no exact value, for the error message.
NO_EXACT_LOG = ("log has no exact rational value; --exact needs rational expressions "
                "(+ - * / min max floor ceil round mod, pow with an integer exponent)")
NO_EXACT_POW = "pow with a non-integer exponent has no exact rational value"
ZERO_POWER = "zero to a negative power"
DIVISION_BY_ZERO = "division by zero (no exact rational value)"
EXPONENT_TOO_LARGE = "pow with an exponent beyond 4096 is not computed exactly"


def as_objects(items: Sequence[Any]) -> np.ndarray:
    """A one-dimensional object array of *items* (numpy would nest sequences)."""
    array = np.empty(len(items), dtype=object)
    array[:] = items
    return array


def bools(values: np.ndarray) -> np.ndarray:
    """*values* as booleans (a 0/1 int used as a condition)."""
    if values.dtype == bool:
        return values
    return np.asarray(values != ZERO, dtype=bool)


def _divide(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    if np.any(right == ZERO):
        raise OperatorError(DIVISION_BY_ZERO)
    return np.asarray(left / right, dtype=object)


def _relation(test: Callable[[Any, Any], Any]) -> Callable[[Any, Any], np.ndarray]:
    return lambda a, b: np.asarray(test(a, b), dtype=bool)


def _logical(test: Callable[[Any, Any], Any]) -> Callable[[Any, Any], np.ndarray]:
    return lambda a, b: np.asarray(test(bools(a), bools(b)), dtype=bool)


#: The binary operators (``&``, ``|`` and ``=>`` strict: the evaluator short-circuits).
BINARY: Mapping[str, Callable[[Any, Any], np.ndarray]] = {
    "&": _logical(np.logical_and),
    "|": _logical(np.logical_or),
    "=>": _logical(lambda a, b: np.logical_or(~a, b)),
    "<=>": _logical(np.equal),
    "=": _relation(np.equal),
    "!=": _relation(np.not_equal),
    "<": _relation(np.less),
    "<=": _relation(np.less_equal),
    ">": _relation(np.greater),
    ">=": _relation(np.greater_equal),
    "+": np.add,
    "-": np.subtract,
    "*": np.multiply,
    "/": _divide,
}


def _extreme(pick: Callable[[Any, Any], Any]) -> Callable[..., np.ndarray]:
    def apply(*args: np.ndarray) -> np.ndarray:
        result = args[0]
        for arg in args[1:]:
            result = pick(result, arg)
        return np.asarray(result, dtype=object)

    return apply


def _checked_int(value: mpq) -> mpq:
    """An int result must fit the ints of :mod:`~veribattery.lang.ops`, as in doubles."""
    if not INT_MIN <= value <= INT_MAX:
        raise OperatorError(f"{value} is out of the int range")
    return value


def _floor(values: np.ndarray) -> np.ndarray:
    return as_objects([_checked_int(mpq(math.floor(x))) for x in values])


def _ceil(values: np.ndarray) -> np.ndarray:
    return as_objects([_checked_int(mpq(math.ceil(x))) for x in values])


def _round(values: np.ndarray) -> np.ndarray:
    """Halves up, as Java's ``Math.round``: ``floor(x + 1/2)``, exact here."""
    return as_objects([_checked_int(mpq(math.floor(x + HALF))) for x in values])


#: Exponents beyond this (of a base other than 0 and +-1) are refused: the exact
#: power would have millions of digits (a double under- or overflows long before).
_LARGEST_EXPONENT = 4096


def power(base: np.ndarray, exponent: np.ndarray, integers: bool) -> np.ndarray:
    """``pow`` exactly: *integers* if both operands are PRISM ints (no negative
    exponent then, and an int result); otherwise the exponent must be whole."""
    if any(e.denominator != 1 for e in exponent):
        raise OperatorError(NO_EXACT_POW)
    if integers and any(e < 0 for e in exponent):
        raise OperatorError(NEGATIVE_EXPONENT)
    out = []
    for b, e in zip(base, exponent, strict=True):
        if b == ZERO and e.numerator < 0:
            raise OperatorError(ZERO_POWER)
        if abs(e) > (64 if integers else _LARGEST_EXPONENT) and abs(b) not in (0, 1):
            raise OperatorError(POW_OVERFLOW if integers else EXPONENT_TOO_LARGE)
        out.append(b ** int(e.numerator))
    return as_objects([_checked_int(v) for v in out] if integers else out)


def _modulo(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    if any(x.denominator != 1 for x in a) or any(y.denominator != 1 for y in b):
        raise OperatorError(MOD_INTEGERS)
    if any(y.numerator <= 0 for y in b):
        raise OperatorError(MOD_DIVISOR)
    pairs = zip(a, b, strict=True)
    return as_objects([mpq(int(x.numerator) % int(y.numerator)) for x, y in pairs])


def _log(x: np.ndarray, base: np.ndarray) -> np.ndarray:
    if len(x):
        raise OperatorError(NO_EXACT_LOG)
    return as_objects([])


#: The built-in functions but ``pow`` (see :func:`power`), on evaluated arguments.
FUNCTIONS: Mapping[str, Callable[..., np.ndarray]] = {
    "min": _extreme(np.minimum),
    "max": _extreme(np.maximum),
    "floor": _floor,
    "ceil": _ceil,
    "round": _round,
    "mod": _modulo,
    "log": _log,
}
