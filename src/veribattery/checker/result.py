"""The outcome of checking one property on one model."""

from __future__ import annotations

import builtins
from dataclasses import dataclass, field, fields, replace
from typing import Literal, get_args

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.certify.bounds import ABSOLUTE_PRECISION, RELATIVE_PRECISION, Bounds
from veribattery.checker.formula.filters import FilterOutcome
from veribattery.errors import ArgumentError, CheckError
from veribattery.lang.nodes import Property

#: What a check keeps: ``"states"``, every state's value and bounds; ``"answers"``,
#: the answer at the initial states and its interval only
#: (:meth:`CheckResult.without_states`), so that one property's per-state vectors are
#: alive at a time (what the CLI prints needs no more).
Keep = Literal["states", "answers"]


def require_keep(keep: object) -> None:
    """Refuse a *keep* outside :data:`Keep`.

    :raises ArgumentError: naming the value given and the ones there are.
    """
    if keep not in get_args(Keep):
        raise ArgumentError(f"keep must be one of {get_args(Keep)}, got {keep!r}")


@dataclass(frozen=True, slots=True)
class CheckResult:
    """A property's value in every state and its value at the initial states.

    Numeric results carry a certified interval: ``lower <= exact <= upper`` for
    the exact value of the model as built (``docs/numerics.md``).

    :param property: the property checked.
    :param values: one value per state (float64 for ``=?``, bool for state formulas).
    :param value: the answer: for booleans True iff the formula holds in *all*
        initial states (as PRISM reports it); for numbers the value at the first
        initial state.
    :param time_s: wall-clock time of the check in seconds.
    :param lower: certified lower bound of a numeric *value* (None for booleans).
    :param upper: certified upper bound of a numeric *value* (None for booleans).
    :param precise: False when the interval is wider than the default precision
        (1e-9 relative or 1e-12 absolute) could be reached.
    :param bounds: the per-state certified bounds of a numeric result.
    :param value_range: for a ``range`` answer (several initial states with
        different values) the lowest and highest value; *value* is then the lowest
        (*lower*/*upper* then enclose the whole range).
    :param printed: the state lines of a ``print``/``printall``/``argmin``/``argmax`` filter.
    :param certified: False for an answer computed in floating point without a
        certificate (``multi(...)``: a linear programme solved by HiGHS); *lower* and
        *upper* then estimate its error and do not bound it, and a boolean may be
        wrong when the query is within that error of its bounds.

    A result made by :meth:`without_states` has an empty *values* and no *bounds*.
    """

    property: Property
    # Per-state arrays are left out of the repr: a notebook would print a million of them.
    values: FloatArray | BoolArray = field(repr=False)
    value: float | bool
    time_s: float
    lower: float | None = None
    upper: float | None = None
    precise: bool = True
    bounds: Bounds | None = field(default=None, repr=False)
    value_range: tuple[float, float] | None = None
    printed: tuple[str, ...] = ()
    certified: bool = True

    @classmethod
    def at_initial(cls, prop: Property, values: Bounds | BoolArray, initial: IntArray,
                   time_s: float) -> CheckResult:
        """Build a result, reducing *values* to the answer at the *initial* states.

        :raises CheckError: when the model has no initial state.
        """
        if len(initial) == 0:
            raise CheckError("the model has no initial state", prop.span)
        if not isinstance(values, Bounds):
            return cls(prop, values, bool(np.all(values[initial])), time_s)
        first = initial[0]
        precise = bool(values.precise_states(RELATIVE_PRECISION, ABSOLUTE_PRECISION)[first])
        return cls(prop, values.value, float(values.value[first]), time_s,
                   float(values.lower[first]), float(values.upper[first]), precise, values)

    @classmethod
    def of_answer(cls, prop: Property, answer: FilterOutcome, time_s: float) -> CheckResult:
        """Build a result from a filter's answer (PRISM's default filter included).

        For a numeric answer *lower*/*upper* are the filter's certified interval
        (for a ``range`` it encloses the whole range).
        """
        value, spread = answer.value, None
        if isinstance(value, tuple):
            spread = None if value[0] == value[1] else value
            value = value[0]
        if value is None:  # pragma: no cover - the default filter always gives a value
            raise AssertionError("no answer")
        per_state = answer.values
        bounds = per_state if isinstance(per_state, Bounds) else None
        points = per_state.value if isinstance(per_state, Bounds) else per_state
        if isinstance(value, bool):
            return cls(prop, points, value, time_s, value_range=spread, printed=answer.printed,
                       certified=answer.certified)
        number = float(value)
        low, high = answer.interval or (number, number)
        return cls(prop, points, number, time_s, low, high, answer.precise, bounds, spread,
                   answer.printed, answer.certified)

    def without_states(self) -> CheckResult:
        """This result without its per-state arrays: *values* empty (same dtype), *bounds*
        None; the answer, its interval and everything else kept.

        For callers that report only the answer: a run of several properties on a
        large model then holds one property's per-state vectors at a time, not all
        of them (four float64 vectors per property: 45 MB at 1.4M states).
        """
        if self.values.size == 0 and self.bounds is None:
            return self
        return replace(self, values=self.values[:0].copy(), bounds=None)

    @builtins.property
    def error(self) -> float:
        """Half the interval's width around *value* at most: ``max(value-lower, upper-value)``."""
        if self.lower is None or self.upper is None or isinstance(self.value, bool):
            return 0.0
        if self.lower == self.upper:
            return 0.0
        return max(self.value - self.lower, self.upper - self.value)

    def __str__(self) -> str:
        label = self.property.name or self.property.text or "property"
        return f"{label}: {self.value}"

    def __repr__(self) -> str:
        # What a notebook shows of a result (and of a run's tuple of them): the
        # property's name and text, not its AST with a span on every node, and none of
        # the per-state arrays (the fields declared repr=False, here and in subclasses).
        prop = self.property
        parts = [f"property=Property(name={prop.name!r}, text={prop.text!r})"] + [
            f"{f.name}={getattr(self, f.name)!r}" for f in fields(self)
            if f.repr and f.name != "property"]
        return f"{type(self).__name__}({', '.join(parts)})"


@dataclass(frozen=True, slots=True, repr=False)  # CheckResult's short repr
class UndecidedResult(CheckResult):
    """A property whose bound neither the certified interval nor exact arithmetic
    decided: its *value* is NaN, and *reason* says why it stays open.

    :param reason: the certified interval that straddled the bound, and why exact
        arithmetic could not settle it.
    """

    reason: str = ""

    @classmethod
    def of(cls, prop: Property, reason: str) -> UndecidedResult:
        """The undecided answer of *prop*, with no per-state values."""
        return cls(prop, np.zeros(0), float("nan"), 0.0, reason=reason)
