"""Requirements ``<property> <op> <bound>`` on a config's named properties.

A requirement on a probability (``P=? [ ... ]``) with a bound outside [0, 1] is bad
input, as PRISM refuses ``P>1.5 [ ... ]``: it would hold always or never, whatever the
mission. The config cannot parse a formula (that is :mod:`veribattery.lang`, above it),
but a probability query is plain in its text: the operator, then one bracketed path
formula that ends it.
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from veribattery._numbers import OutOfRange, exact_number
from veribattery.config.exact import brief, show

__all__ = ["Requirement", "is_property_name", "parse_requirement", "requirement_problem"]

_REQUIREMENT = re.compile(r"\s*([A-Za-z_]\w*)\s*(<=|>=|<|>)\s*(\S+)\s*")
_IDENT = re.compile(r"[A-Za-z_]\w*")
#: A formula that is only a reference to another property: ``"p_success"``.
_REFERENCE = re.compile(r'\s*"([A-Za-z_]\w*)"\s*')
#: ``P=? [``, ``Pmax=? [``, or steady-state ``S=? [`` at a formula's start.
_PROBABILITY = re.compile(r"\s*(?:P(?:min|max)?|S)\s*=\s*\?\s*\[")


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


def is_property_name(name: str) -> bool:
    """Whether *name* may name a property: an identifier (``p_success``, not ``1bad``)."""
    return _IDENT.fullmatch(name) is not None


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


def requirement_problem(requirement: Requirement, formula: str,
                        properties: Mapping[str, str] | None = None) -> str | None:
    """What is wrong with *requirement* on a property of *formula*, or None: a bound
    outside [0, 1] on a probability.

    :param properties: the other properties by name, to follow a formula that is a
        reference to one (``"p_success"``) to what it names.
    """
    if 0 <= requirement.bound <= 1:
        return None
    named = _followed(formula, properties or {})
    if not _is_probability(named):
        return None
    shown = formula.strip() if named is formula else f"{formula.strip()}, {named.strip()}"
    return (f"{requirement.prop} is a probability ({shown}): the bound must be in "
            f"[0, 1], got {brief(requirement.bound)}")


def _followed(formula: str, properties: Mapping[str, str]) -> str:
    """*formula*, or where it is only a reference ``"name"`` to another property, the
    formula that one names in the end (*formula* itself on a cycle)."""
    seen: set[str] = set()
    current = formula
    while (reference := _REFERENCE.fullmatch(current)) is not None:
        name = reference.group(1)
        if name in seen or name not in properties:
            return formula if name in seen else current
        seen.add(name)
        current = properties[name]
    return current


def _is_probability(formula: str) -> bool:
    """Whether *formula* is a probability query: ``P=? [ ... ]`` and nothing after."""
    start = _PROBABILITY.match(formula)
    if start is None:
        return False
    depth, quoted = 0, False
    for index in range(start.end() - 1, len(formula)):
        char = formula[index]
        quoted = quoted != (char == '"')
        if not quoted:
            depth += (char == "[") - (char == "]")
        if depth == 0:
            return not formula[index + 1:].strip()
    return False
