"""Properties as expressions: PRISM's operators and functions over per-state arrays.

``P=? [F a] + P=? [F b]``, ``1 - S=? [..]``, ``round(R=? [..])``: once the
operators are computed (one value per state), the expression around them is
evaluated state-wise here, with PRISM's rules (``/`` is real division; ``pow``
of ints is an int and rejects a negative exponent; ``mod`` takes ints).
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from veribattery._types import BoolArray
from veribattery.errors import CheckError, Span

#: Per-state values: bool, int or float64 (ints stay ints, as in PRISM's types).
Values = npt.NDArray[Any]

_BINARY: dict[str, Callable[[Values, Values], Values]] = {
    "&": np.logical_and,
    "|": np.logical_or,
    "=>": lambda a, b: np.logical_or(np.logical_not(a), b),
    "<=>": operator.eq,
    "=": operator.eq,
    "!=": operator.ne,
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
    "+": operator.add,
    "-": operator.sub,
    "*": operator.mul,
    "/": np.true_divide,
}


def _is_int(values: Values) -> bool:
    return bool(np.issubdtype(values.dtype, np.integer))


def unary(op: str, operand: Values, span: Span | None = None) -> Values:
    """``!a`` or ``-a`` state by state."""
    if op == "!":
        return np.asarray(np.logical_not(operand))
    return np.asarray(-operand)


_LOGICAL = frozenset({"&", "|", "=>", "<=>"})


def _check_types(op: str, left: Values, right: Values, span: Span | None) -> None:
    """The type rules of :mod:`veribattery.lang.typecheck`, for unchecked formulas."""
    bools = (left.dtype == np.bool_, right.dtype == np.bool_)
    if op in _LOGICAL and not all(bools):
        raise CheckError(f"type error: '{op}' needs bools (a query =? gives a number)", span)
    if op not in _LOGICAL and op not in ("=", "!=") and any(bools):
        raise CheckError(f"type error: '{op}' needs numbers, and a bounded operator "
                         "gives a bool", span)


def binary(op: str, left: Values, right: Values, span: Span | None = None) -> Values:
    """``left op right`` state by state (``/`` is real division, as in PRISM)."""
    if op not in _BINARY:
        raise CheckError(f"unknown operator '{op}'", span)
    _check_types(op, left, right, span)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.asarray(_BINARY[op](left, right))


def choose(cond: BoolArray, then: Values, otherwise: Values) -> Values:
    """``cond ? then : otherwise`` state by state."""
    return np.asarray(np.where(cond, then, otherwise))


def _power(base: Values, exponent: Values, span: Span | None) -> Values:
    if _is_int(base) and _is_int(exponent):
        if np.any(exponent < 0):
            raise CheckError("pow(...) of ints needs a non-negative exponent "
                             "(write a double, e.g. -1.0, for a real power)", span)
        return np.asarray(np.power(base, exponent))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return np.asarray(np.power(base.astype(np.float64), exponent))


def _mod(a: Values, b: Values, span: Span | None) -> Values:
    if not (_is_int(a) and _is_int(b)):
        raise CheckError("mod(...) needs int arguments", span)
    if np.any(b == 0):
        raise CheckError("mod(..., 0): division by zero", span)
    return np.asarray(np.mod(a, b))


def _rounded(fn: Callable[[Values], Values], a: Values) -> Values:
    """An int array, unless infinities or NaN (from a reward) must survive."""
    if _is_int(a):
        return a
    result = np.asarray(fn(a))
    return result.astype(np.int64) if np.all(np.isfinite(result)) else result


def call(func: str, args: Sequence[Values], span: Span | None = None) -> Values:
    """A PRISM built-in function state by state.

    ``round`` rounds half up (``floor(x + 0.5)``), as PRISM (Java's Math.round) does.
    """
    if func == "min":
        return np.asarray(np.minimum.reduce(np.broadcast_arrays(*args)))
    if func == "max":
        return np.asarray(np.maximum.reduce(np.broadcast_arrays(*args)))
    if func == "floor":
        return _rounded(np.floor, args[0])
    if func == "ceil":
        return _rounded(np.ceil, args[0])
    if func == "round":
        return _rounded(lambda x: np.floor(x + 0.5), args[0])
    if func == "pow":
        return _power(args[0], args[1], span)
    if func == "mod":
        return _mod(args[0], args[1], span)
    if func == "log":
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.asarray(np.log(args[0]) / np.log(args[1]))
    raise CheckError(f"unknown function '{func}'", span)
