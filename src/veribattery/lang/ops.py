"""PRISM's operators and built-in functions: the one table of their semantics.

Every evaluator of expressions follows this table: constant folding
(:mod:`veribattery.lang.evaluate`), the builder's numpy kernels, exact rationals and
the checker's intervals. Per operator it gives the number of operands, the type
rule (:meth:`Operator.result`), whether later operands are evaluated only when the
first leaves the value open (:attr:`Operator.lazy`), whether some operands have no
value at all (:attr:`Operator.fails`: an error, as in PRISM, not a NaN), and the
reference value on Python scalars (:attr:`Operator.apply`), where ``int`` is PRISM's
int, ``float`` its double and ``bool`` its bool.

The semantics are those of PRISM's floating-point evaluator (its manual's
"Expressions" page and ``parser.ast.ExpressionBinaryOp``/``ExpressionFunc``): ``/``
is always double division, so ``x/0`` is +-infinity and ``0/0`` NaN, as in Java;
``pow`` of two ints is an int and rejects a negative exponent; ``mod`` takes ints and
a positive divisor and is never negative; ``floor``, ``ceil`` and ``round`` give
ints and fail on NaN and infinity; ``round`` rounds halves up; ``log(x, b)`` is NaN
for a base that is not positive, 1 or infinite; ``min``/``max`` take one or more
numbers and are ints iff all are. See docs/expressions.md for the table as prose.

Pure Python: the numpy, rational and interval domains live in
:mod:`veribattery.explore.compile.arrays`, :mod:`veribattery.explore.exact.rational_ops` and
:mod:`veribattery.checker.formula.intervals`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from veribattery.errors import VeribatteryError
from veribattery.lang.nodes import Value, ValueType

__all__ = [
    "BINARY",
    "CONDITIONAL",
    "FUNCTIONS",
    "INT_MAX",
    "INT_MIN",
    "MOD_DIVISOR",
    "MOD_INTEGERS",
    "NEGATIVE_EXPONENT",
    "POW_OVERFLOW",
    "UNARY",
    "Operator",
    "OperatorError",
    "ceil_int",
    "conditional_type",
    "decided_by",
    "divide",
    "floor_int",
    "int_literal",
    "int_pow",
    "java_log",
    "java_max",
    "java_min",
    "java_pow",
    "modulo",
    "not_an_int",
    "out_of_int_range",
    "round_int",
    "show_int",
]


class OperatorError(VeribatteryError):
    """An operator has no value for its operands (``mod(x, 0)``, ``floor(1/0)``).

    Raised without a position; each evaluator re-raises it as its own error class
    with the position of the expression.
    """


#: PRISM's ints are held in 64 bits here (PRISM's own are 32).
INT_MIN = -(1 << 63)
INT_MAX = (1 << 63) - 1

# The messages of the errors, shared by every evaluator.
#: The most digits an int literal may have: Python reads no more than 4,300 into an int.
_LITERAL_DIGITS = 4_000
NEGATIVE_EXPONENT = "negative exponent in integer pow (for a real power write a double: -1.0)"
POW_OVERFLOW = "integer pow out of the int range"
MOD_DIVISOR = "modulo with non-positive divisor"
MOD_INTEGERS = "mod requires integer arguments"


def show_int(value: int) -> str:
    """*value* in digits, or its number of digits if it has more than 40 (counted without
    writing them: Python refuses to write an int of more than 4,300 digits)."""
    if abs(value) < 10**40:
        return str(value)
    digits = int(math.log10(abs(value)))
    digits += 10**digits <= abs(value)  # log10 is a float: one off near a power of ten
    return f"{'-' if value < 0 else ''}<{digits} digits>"


def out_of_int_range(value: int) -> str:
    """The message for an int (a literal, a constant, a folded expression) that the
    engine's 64-bit ints cannot hold."""
    return _beyond_ints(show_int(value))


def int_literal(text: str) -> int:
    """The int an int literal writes (digits only).

    :raises OperatorError: for more digits than Python reads into an int (4,300), far
        beyond the 64-bit range anyway.
    """
    digits = len(text.lstrip("0"))
    if digits > _LITERAL_DIGITS:
        raise OperatorError(_beyond_ints(f"<{digits:,} digits>"))
    return int(text)


def _beyond_ints(shown: str) -> str:
    return (f"{shown} is out of the int range -2^63..2^63-1 (ints are 64-bit here; PRISM's "
            "are 32-bit): use a smaller int, or a double such as 1e19")


def not_an_int(name: str, value: float) -> str:
    """The message for ``floor``/``ceil``/``round`` of a value that has no int."""
    if value != value:
        shown = "NaN"
    elif math.isinf(value):
        shown = "inf" if value > 0 else "-inf"
    else:
        shown = repr(value)
    return f"cannot take {name} of {shown}: no int value"


# ---------------------------------------------------------------------------
# Type rules
# ---------------------------------------------------------------------------

_NUMBERS = frozenset({"int", "double"})
#: A type rule: the result type for the operand types, or None for a type error.
TypeRule = Callable[[Sequence[ValueType]], ValueType | None]


def _bools(kinds: Sequence[ValueType]) -> ValueType | None:
    return "bool" if all(k == "bool" for k in kinds) else None


def _joined(kinds: Sequence[ValueType]) -> ValueType | None:
    """Numbers: int iff all are ints (``+``, ``pow``, ``min``...)."""
    if not all(k in _NUMBERS for k in kinds):
        return None
    return "int" if all(k == "int" for k in kinds) else "double"


def _double(kinds: Sequence[ValueType]) -> ValueType | None:
    return "double" if all(k in _NUMBERS for k in kinds) else None


def _int(kinds: Sequence[ValueType]) -> ValueType | None:
    return "int" if all(k in _NUMBERS for k in kinds) else None


def _ints(kinds: Sequence[ValueType]) -> ValueType | None:
    return "int" if all(k == "int" for k in kinds) else None


def _compared(kinds: Sequence[ValueType]) -> ValueType | None:
    return "bool" if all(k in _NUMBERS for k in kinds) else None


def _equated(kinds: Sequence[ValueType]) -> ValueType | None:
    """``=``/``!=``: two bools or two numbers."""
    return "bool" if _bools(kinds) or _joined(kinds) else None


def conditional_type(then: ValueType, otherwise: ValueType) -> ValueType | None:
    """The type of ``c ? a : b``: the branches' common type, double for int and double."""
    if then == otherwise:
        return then
    return "double" if then in _NUMBERS and otherwise in _NUMBERS else None


# ---------------------------------------------------------------------------
# The operators
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Operator:
    """One operator or built-in function of PRISM's expressions.

    :param name: its symbol (``+``) or function name (``pow``).
    :param arity: the least and the most operands (None: no most).
    :param result: the result type for the operand types (None: a type error).
    :param apply: the value for evaluated operands (typed Python scalars).
    :param lazy: the first operand may decide the value alone; the second is then
        not evaluated (PRISM's ``&``, ``|``, ``=>``; see :func:`decided_by`).
    :param fails: whether, for operands of these types, some values have no result:
        :class:`OperatorError`, which a vectorised evaluator must not raise for a
        state that does not evaluate the operator (``floor`` of an int never fails,
        of a double it does for NaN).
    """

    name: str
    arity: tuple[int, int | None]
    result: TypeRule
    apply: Callable[..., Value]
    lazy: bool = False
    fails: Callable[[Sequence[ValueType]], bool] = lambda kinds: False

    @property
    def may_fail(self) -> bool:
        """Whether some operands of some types have no result."""
        return self.fails(("double", "double")) or self.fails(("int", "int"))

    def accepts(self, count: int) -> bool:
        """Whether *count* operands are allowed."""
        low, high = self.arity
        return low <= count and (high is None or count <= high)


def decided_by(op: str, left: bool) -> bool | None:
    """The value of ``left op right`` if *left* alone decides it (``&``, ``|``, ``=>``)."""
    if op == "&":
        return False if not left else None
    if op == "|":
        return True if left else None
    if op == "=>":
        return True if not left else None
    return None


# ----------------------------------------------------------- arithmetic


def divide(a: Value, b: Value) -> float:
    """``a / b`` in doubles, as Java: ``x/0`` is +-infinity, ``0/0`` and NaN/0 are NaN."""
    x, y = float(a), float(b)
    if y == 0.0:
        if x == 0.0 or x != x:
            return math.nan
        return math.copysign(math.inf, x) * math.copysign(1.0, y)
    return x / y


def _is_odd_integer(x: float) -> bool:
    return math.isfinite(x) and x == math.floor(x) and math.fmod(x, 2.0) != 0.0


def java_pow(a: float, b: float) -> float:
    """Java's ``Math.pow`` (the C library's ``pow``, but NaN for a NaN exponent and
    for ``pow(+-1, +-inf)``); never an error: NaN or infinity instead.

    Every evaluator of doubles computes powers with this function (the numpy
    domain element by element): numpy's own ``pow`` may differ in the last bit,
    and differently for a constant exponent and for one per state.
    """
    if b != b or (abs(a) == 1.0 and math.isinf(b)):
        return math.nan
    try:
        return math.pow(a, b)
    except OverflowError:
        return -math.inf if a < 0 and _is_odd_integer(b) else math.inf
    except ValueError:  # zero to a negative power, or a negative base to a fraction
        if a == 0.0:
            negative = math.copysign(1.0, a) < 0 and _is_odd_integer(b)
            return -math.inf if negative else math.inf
        return math.nan


def int_pow(a: int, b: int) -> int:
    """``pow`` of two ints: an int; a negative exponent or a result beyond the int
    range is an error (PRISM: "Negative exponent not allowed for integer power")."""
    if b < 0:
        raise OperatorError(NEGATIVE_EXPONENT)
    if abs(a) > 1 and b > 64:  # at least 2**65: do not compute it
        raise OperatorError(POW_OVERFLOW)
    result = int(a**b)
    if not INT_MIN <= result <= INT_MAX:
        raise OperatorError(POW_OVERFLOW)
    return result


def _power(a: Value, b: Value) -> Value:
    if type(a) is int and type(b) is int:
        return int_pow(a, b)
    return java_pow(float(a), float(b))


def modulo(i: Value, n: Value) -> int:
    """PRISM's ``mod``: ints only, a positive divisor, a result in ``0..n-1``."""
    if type(i) is not int or type(n) is not int:
        raise OperatorError(MOD_INTEGERS)
    if n <= 0:
        raise OperatorError(MOD_DIVISOR)
    return i % n


def _natural_log(x: float) -> float:
    if x != x or x < 0:
        return math.nan
    if x == 0.0:
        return -math.inf
    return math.inf if math.isinf(x) else math.log(x)


def java_log(x: Value, b: Value) -> float:
    """``log(x, b)`` as PRISM: NaN for a base <= 0, 1, infinite or NaN; else
    ``ln x / ln b`` with Java's ``ln`` (``ln 0 = -inf``, ``ln`` of a negative is NaN),
    computed, as :func:`java_pow`, with the C library in every evaluator."""
    base = float(b)
    if not base > 0 or base == 1.0 or math.isinf(base):
        return math.nan
    return _natural_log(float(x)) / _natural_log(base)


def java_min(a: float, b: float) -> float:
    """Java's ``Math.min``: NaN if either is, and -0.0 below 0.0."""
    if a != a or b != b:
        return math.nan
    if a == 0.0 and b == 0.0:
        negative = math.copysign(1.0, a) < 0 or math.copysign(1.0, b) < 0
        return -0.0 if negative else 0.0
    return a if a <= b else b


def java_max(a: float, b: float) -> float:
    """Java's ``Math.max``: NaN if either is, and 0.0 above -0.0."""
    if a != a or b != b:
        return math.nan
    if a == 0.0 and b == 0.0:
        negative = math.copysign(1.0, a) < 0 and math.copysign(1.0, b) < 0
        return -0.0 if negative else 0.0
    return a if a >= b else b


def _extreme(pick: Callable[[float, float], float], ints: Callable[..., int]) -> Callable[
        ..., Value]:
    def apply(*args: Value) -> Value:
        if all(type(a) is int for a in args):
            return ints(args)
        result = float(args[0])
        for arg in args[1:]:
            result = pick(result, float(arg))
        return result

    return apply


def _as_int(name: str, value: float) -> int:
    """*value* (integral or not finite) as an int, or the error PRISM reports."""
    if not math.isfinite(value) or not INT_MIN <= value <= INT_MAX:
        raise OperatorError(not_an_int(name, value))
    return int(value)


def floor_int(x: Value) -> int:
    """``floor``: an int; NaN and infinity are errors."""
    return x if type(x) is int else _as_int("floor", math.floor(x) if math.isfinite(x) else x)


def ceil_int(x: Value) -> int:
    """``ceil``: an int; NaN and infinity are errors."""
    return x if type(x) is int else _as_int("ceil", math.ceil(x) if math.isfinite(x) else x)


def round_int(x: Value) -> int:
    """``round``: the nearest int, halves up (Java's ``Math.round``: ``round(-1.5) = -1``,
    and ``round(0.49999999999999994) = 0``, which ``floor(x + 0.5)`` gets wrong)."""
    if type(x) is int:
        return x
    value = float(x)
    if not math.isfinite(value):
        return _as_int("round", value)
    low = math.floor(value)
    return _as_int("round", low + 1 if value - low >= 0.5 else low)


def _equal(a: Value, b: Value) -> bool:
    return a == b


def _relation(test: Callable[[Any, Any], bool]) -> Callable[[Value, Value], bool]:
    return lambda a, b: bool(test(a, b))


def _of_a_double(kinds: Sequence[ValueType]) -> bool:
    """``floor``, ``ceil``, ``round``: NaN and infinity have no int; an int is itself."""
    return kinds[0] == "double"


def _of_ints(kinds: Sequence[ValueType]) -> bool:
    """``pow``: of ints, a negative exponent or an overflow; of doubles, NaN at worst."""
    return all(k == "int" for k in kinds)


_ANY = (1, 1)
_TWO = (2, 2)

UNARY: Mapping[str, Operator] = {
    "!": Operator("!", _ANY, _bools, lambda a: not a),
    "-": Operator("-", _ANY, _joined, lambda a: -a),
}

BINARY: Mapping[str, Operator] = {
    "&": Operator("&", _TWO, _bools, lambda a, b: bool(a) and bool(b), lazy=True),
    "|": Operator("|", _TWO, _bools, lambda a, b: bool(a) or bool(b), lazy=True),
    "=>": Operator("=>", _TWO, _bools, lambda a, b: (not a) or bool(b), lazy=True),
    "<=>": Operator("<=>", _TWO, _bools, lambda a, b: bool(a) == bool(b)),
    "=": Operator("=", _TWO, _equated, _equal),
    "!=": Operator("!=", _TWO, _equated, lambda a, b: not _equal(a, b)),
    "<": Operator("<", _TWO, _compared, _relation(lambda a, b: a < b)),
    "<=": Operator("<=", _TWO, _compared, _relation(lambda a, b: a <= b)),
    ">": Operator(">", _TWO, _compared, _relation(lambda a, b: a > b)),
    ">=": Operator(">=", _TWO, _compared, _relation(lambda a, b: a >= b)),
    "+": Operator("+", _TWO, _joined, lambda a, b: a + b),
    "-": Operator("-", _TWO, _joined, lambda a, b: a - b),
    "*": Operator("*", _TWO, _joined, lambda a, b: a * b),
    "/": Operator("/", _TWO, _double, divide),
}

FUNCTIONS: Mapping[str, Operator] = {
    "min": Operator("min", (1, None), _joined, _extreme(java_min, min)),
    "max": Operator("max", (1, None), _joined, _extreme(java_max, max)),
    "floor": Operator("floor", _ANY, _int, floor_int, fails=_of_a_double),
    "ceil": Operator("ceil", _ANY, _int, ceil_int, fails=_of_a_double),
    "round": Operator("round", _ANY, _int, round_int, fails=_of_a_double),
    "pow": Operator("pow", _TWO, _joined, _power, fails=_of_ints),
    "mod": Operator("mod", _TWO, _ints, modulo, fails=lambda kinds: True),
    "log": Operator("log", _TWO, _double, java_log),
}

#: ``cond ? then : otherwise``: only the branch the condition picks is evaluated.
CONDITIONAL = Operator(
    "? :", (3, 3),
    lambda kinds: conditional_type(kinds[1], kinds[2]) if kinds[0] == "bool" else None,
    lambda c, a, b: a if c else b, lazy=True,
)
