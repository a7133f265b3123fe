"""PRISM's operators over numpy arrays: the float domain of :mod:`veribattery.lang.ops`.

An operand is an array with one value per state, or a 0-d array or numpy scalar for
a constant; ints are int64, doubles float64 and bools bool (boolean variables may
arrive as 0/1 ints, which the logical operators and comparisons treat correctly).
Each function computes, element by element, the reference value of
:mod:`veribattery.lang.ops` (``tests/lang/test_operator_agreement.py`` holds them
together) and raises :class:`~veribattery.lang.ops.OperatorError` if an element has
none. A result over 0-d operands is a numpy scalar.

These run once per expression node and BFS layer: the common operators are numpy's
ufuncs themselves, and the special cases of the others (a zero divisor, a signed
zero) are looked for only with one cheap test.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from veribattery.lang.ops import (
    MOD_DIVISOR,
    MOD_INTEGERS,
    NEGATIVE_EXPONENT,
    OperatorError,
    int_pow,
    java_log,
    java_pow,
    not_an_int,
)

__all__ = [
    "BINARY",
    "FUNCTIONS",
    "UNARY",
    "divide",
    "iff",
    "is_int",
    "maximum",
    "minimum",
    "rounded_half_up",
]

#: An operation of this domain: arrays (or numpy scalars) in, an array or scalar out.
ArrayOp = Callable[..., Any]


def is_int(x: Any) -> bool:
    """Whether *x* holds PRISM ints (a 0/1 boolean variable counts as one)."""
    return np.asarray(x).dtype.kind in "iub"


def divide(a: Any, b: Any) -> Any:
    """``a / b`` in doubles: ``x/0`` is +-infinity and ``0/0`` NaN, as in Java."""
    if np.any(np.asarray(b) == 0):  # the rare case: numpy would warn
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.true_divide(a, b, dtype=np.float64)
    return np.true_divide(a, b, dtype=np.float64)


def iff(a: Any, b: Any) -> Any:
    """``a <=> b``."""
    return np.equal(np.asarray(a, dtype=bool), np.asarray(b, dtype=bool))


def implies(a: Any, b: Any) -> Any:
    """``a => b``."""
    return np.logical_or(np.logical_not(a), b)


# ---------------------------------------------------------------------------
# min and max: Java's Math.min/max, folded over the arguments
# ---------------------------------------------------------------------------


def minimum(*xs: Any) -> Any:
    """``min(...)``: an int iff all arguments are; NaN if any is; -0.0 below 0.0."""
    return _extreme(np.minimum, True, xs)


def maximum(*xs: Any) -> Any:
    """``max(...)``: an int iff all arguments are; NaN if any is; 0.0 above -0.0."""
    return _extreme(np.maximum, False, xs)


def _extreme(pick: Callable[[Any, Any], Any], negative_zero: bool, xs: tuple[Any, ...]) -> Any:
    result = xs[0]
    for x in xs[1:]:
        result = pick(result, x)
    if len(xs) > 1 and np.asarray(result).dtype.kind == "f":
        zero = np.asarray(result) == 0
        if zero.any():  # numpy keeps either zero; Java orders -0.0 below 0.0
            result = _signed_zero(result, zero, negative_zero, xs)
    return result


def _signed_zero(result: Any, zero: Any, negative_zero: bool, xs: tuple[Any, ...]) -> Any:
    """*result* with its zeros signed as Java's: min is -0.0 if any argument is -0.0,
    max is 0.0 if any argument is 0.0 (the other arguments are on the far side)."""
    found = np.zeros(np.shape(zero), dtype=bool)
    for x in xs:  # a zero of the sign that wins: -0.0 for min, 0.0 for max
        values = np.asarray(x, dtype=np.float64)
        found |= (values == 0) & (np.signbit(values) == negative_zero)
    signed = np.where(found == negative_zero, -0.0, 0.0)
    return np.asarray(np.where(zero, signed, result))[()]


# ---------------------------------------------------------------------------
# floor, ceil, round: doubles to ints, NaN and infinity refused
# ---------------------------------------------------------------------------

_INT_LOW = -(2.0**63)
_INT_HIGH = 2.0**63


def _ints(name: str, values: Any) -> Any:
    """Integral doubles *values* as int64, or the error for the first one without."""
    values = np.asarray(values)
    fits = (values >= _INT_LOW) & (values < _INT_HIGH)  # False for NaN
    if not fits.all():
        raise OperatorError(not_an_int(name, float(values[~fits].flat[0])))
    return values.astype(np.int64)[()]


def floor(x: Any) -> Any:
    """``floor(x)``: an int."""
    if is_int(x):
        return np.asarray(x, dtype=np.int64)[()]
    return _ints("floor", np.floor(x))


def ceil(x: Any) -> Any:
    """``ceil(x)``: an int."""
    if is_int(x):
        return np.asarray(x, dtype=np.int64)[()]
    return _ints("ceil", np.ceil(x))


def round_half_up(x: Any) -> Any:
    """``round(x)``: the nearest int, halves up, as Java's ``Math.round``."""
    if is_int(x):
        return np.asarray(x, dtype=np.int64)[()]
    return _ints("round", rounded_half_up(x))


def rounded_half_up(x: Any) -> Any:
    """*x* rounded to the nearest whole double, halves up (infinities stay; NaN too).

    ``floor(x + 0.5)`` would round 0.49999999999999994 up (the sum rounds to 1.0);
    the fraction ``x - floor(x)`` of a double is exact, and compared with 1/2 instead.
    """
    low = np.floor(x)
    with np.errstate(invalid="ignore"):  # inf - inf: NaN, which compares false
        up = (np.asarray(x) - low) >= 0.5
    return np.asarray(np.where(up, low + 1, low))[()]


# ---------------------------------------------------------------------------
# pow, mod, log
# ---------------------------------------------------------------------------

def _rows_of(x: Any, other: Any) -> Any:
    """*x* as it meets *other*, row for row: a constant divisor of no row is none."""
    x = np.asarray(x)
    if x.ndim == 0 and np.ndim(other):
        return np.broadcast_to(x, np.shape(other))
    return x


#: Int powers at least this large are checked against the int range exactly.
_POW_CHECK = 2.0**62


def power(a: Any, b: Any) -> Any:
    """``pow(a, b)``: ints for two ints (no negative exponent, no overflow); else
    Java's ``Math.pow`` in doubles (NaN or infinity, never an error)."""
    if is_int(a) and is_int(b):
        return _int_power(np.asarray(a, np.int64), np.asarray(b, np.int64))
    return _doubles(_JAVA_POW(np.asarray(a, np.float64), np.asarray(b, np.float64)))


def _doubles(values: Any) -> Any:
    return np.asarray(values, dtype=np.float64)[()]


# pow and log of doubles, element by element with the C library as the reference
# computes them: numpy's vectorised pow and log may differ in the last bit (and its
# pow differently for a constant exponent); they are rare, and usually tabulated.
_JAVA_POW = np.frompyfunc(java_pow, 2, 1)
_JAVA_LOG = np.frompyfunc(java_log, 2, 1)


def _int_power(base: Any, exponent: Any) -> Any:
    if np.any(_rows_of(exponent, base) < 0):
        raise OperatorError(NEGATIVE_EXPONENT)
    result = np.power(base, exponent)  # wraps on overflow: checked below
    with np.errstate(over="ignore"):
        size = np.abs(np.power(base.astype(np.float64), exponent.astype(np.float64)))
    large = size >= _POW_CHECK
    if large.any():
        pairs = np.broadcast_arrays(base, exponent)
        for a, b in zip(pairs[0][large].flat, pairs[1][large].flat, strict=True):
            int_pow(int(a), int(b))  # raises beyond the int range
    return np.asarray(result)[()]


def modulo(a: Any, b: Any) -> Any:
    """``mod(a, b)``: ints, a positive divisor, a result in ``0..b-1``."""
    if not (is_int(a) and is_int(b)):
        raise OperatorError(MOD_INTEGERS)
    if np.any(_rows_of(b, a) <= 0):
        raise OperatorError(MOD_DIVISOR)
    return np.mod(np.asarray(a, np.int64), np.asarray(b, np.int64))[()]


def log(x: Any, base: Any) -> Any:
    """``log(x, base)``: ``ln x / ln base``, NaN for a base <= 0, 1 or infinite."""
    return _doubles(_JAVA_LOG(np.asarray(x, np.float64), np.asarray(base, np.float64)))


UNARY: Mapping[str, ArrayOp] = {"!": np.logical_not, "-": np.negative}

#: The strict binary operators (``&``, ``|`` and ``=>`` here evaluate both sides:
#: the evaluators that short-circuit do so before they call them).
BINARY: Mapping[str, ArrayOp] = {
    "&": np.logical_and,
    "|": np.logical_or,
    "=>": implies,
    "<=>": iff,
    "=": np.equal,
    "!=": np.not_equal,
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
    "+": np.add,
    "-": np.subtract,
    "*": np.multiply,
    "/": divide,
}

FUNCTIONS: Mapping[str, ArrayOp] = {
    "min": minimum,
    "max": maximum,
    "floor": floor,
    "ceil": ceil,
    "round": round_half_up,
    "pow": power,
    "mod": modulo,
    "log": log,
}
