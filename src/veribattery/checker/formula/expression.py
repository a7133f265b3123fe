"""Properties as expressions: PRISM's operators and functions over per-state arrays.

``P=? [F a] + P=? [F b]``, ``1 - S=? [..]``, ``round(R=? [..])``: once the
operators are computed (one value per state), the expression around them is
evaluated state-wise here, with the operators of :mod:`veribattery.lang.ops` in
the numpy domain of :mod:`veribattery.explore.compile.arrays` (``/`` is real division;
``pow`` of ints is an int and rejects a negative exponent; ``mod`` takes ints),
after the type checks that an unchecked formula still needs.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from veribattery._types import BoolArray
from veribattery.errors import CheckError, Span
from veribattery.explore.compile import arrays
from veribattery.lang import ops
from veribattery.lang.ops import OperatorError

#: Per-state values: bool, int or float64 (ints stay ints, as in PRISM's types).
Values = npt.NDArray[Any]


def unary(op: str, operand: Values, span: Span | None = None) -> Values:
    """``!a`` or ``-a`` state by state."""
    return np.asarray(arrays.UNARY[op](operand))


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
    if op not in arrays.BINARY:
        raise CheckError(f"unknown operator '{op}'", span)
    _check_types(op, left, right, span)
    # values may be infinite, and doubles overflow to infinity (as in PRISM's Java)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return np.asarray(arrays.BINARY[op](left, right))


def choose(cond: BoolArray, then: Values, otherwise: Values) -> Values:
    """``cond ? then : otherwise`` state by state."""
    return np.asarray(np.where(cond, then, otherwise))


def call(func: str, args: Sequence[Values], span: Span | None = None) -> Values:
    """A PRISM built-in function state by state.

    ``round`` rounds half up, as PRISM (Java's Math.round) does; ``floor``, ``ceil``
    and ``round`` of an infinite value (a reward) are errors, as in PRISM.
    """
    function = ops.FUNCTIONS.get(func)
    if function is None:
        raise CheckError(f"unknown function '{func}'", span)
    if not function.accepts(len(args)):
        raise CheckError(f"wrong number of arguments to {func}", span)
    try:
        with np.errstate(all="ignore"):  # values may be infinite
            return np.asarray(arrays.FUNCTIONS[func](*args))
    except OperatorError as exc:
        raise CheckError(f"{func}(...): {exc}", span) from None
