"""Requirements ``<property> <op> <bound>`` on a config's named properties."""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from veribattery._numbers import OutOfRange, exact_number
from veribattery.config.exact import show

__all__ = ["Requirement", "parse_requirement"]

_REQUIREMENT = re.compile(r"\s*([A-Za-z_]\w*)\s*(<=|>=|<|>)\s*(\S+)\s*")


@dataclass(frozen=True, slots=True)
class Requirement:
    """A requirement ``<property> <op> <bound>``, e.g. ``p_success >= 0.99``."""

    prop: str
    op: str
    bound: Fraction

    def holds(self, value: float) -> bool:
        """Whether a checked *value* meets this requirement, compared exactly with the
        rational bound (which a float may not hold: ``1/3``, or ``1e400`` beyond the
        doubles); NaN meets none."""
        ops: dict[str, Callable[[Any, Any], bool]] = {
            "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge}
        value = float(value)
        if value != value:
            return False
        return ops[self.op](value if math.isinf(value) else Fraction(value), self.bound)

    def __str__(self) -> str:
        return f"{self.prop} {self.op} {show(self.bound)}"


def parse_requirement(text: str) -> Requirement:
    """Parse ``name op number`` (op one of ``< <= > >=``).

    :raises ValueError: when *text* is not of that form, or the number is out of range.
    """
    match = _REQUIREMENT.fullmatch(text)
    if match is None:
        raise ValueError(f"must look like 'p_success >= 0.99' (op: <, <=, >, >=), got {text!r}")
    try:
        bound = exact_number(match.group(3))
    except OutOfRange as exc:
        raise ValueError(f"bound {exc}") from None
    except ValueError:
        raise ValueError(f"bound must be a number, got {match.group(3)!r}") from None
    return Requirement(match.group(1), match.group(2), bound)
