"""The outcome of checking one property on one model."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.errors import CheckError
from veribattery.lang.nodes import Property


@dataclass(frozen=True, slots=True)
class CheckResult:
    """A property's value in every state and its value at the initial states.

    :param property: the property checked.
    :param values: one value per state (float64 for ``=?``, bool for state formulas).
    :param value: the answer: for booleans True iff the formula holds in *all*
        initial states (as PRISM reports it); for numbers the value at the first
        initial state.
    :param time_s: wall-clock time of the check in seconds.
    :param value_range: for a ``range`` answer (several initial states with
        different values) the lowest and highest value; *value* is then the lowest.
    :param printed: the state lines of a ``print``/``printall``/``argmin``/``argmax`` filter.
    """

    property: Property
    values: FloatArray | BoolArray
    value: float | bool
    time_s: float
    value_range: tuple[float, float] | None = None
    printed: tuple[str, ...] = ()

    @classmethod
    def at_initial(cls, prop: Property, values: FloatArray | BoolArray, initial: IntArray,
                   time_s: float) -> CheckResult:
        """Build a result, reducing *values* to the answer at the *initial* states.

        :raises CheckError: when the model has no initial state.
        """
        if len(initial) == 0:
            raise CheckError("the model has no initial state", prop.span)
        if values.dtype == np.bool_:
            return cls(prop, values, bool(np.all(values[initial])), time_s)
        return cls(prop, values, float(values[initial[0]]), time_s)

    def __str__(self) -> str:
        label = self.property.name or self.property.text or "property"
        return f"{label}: {self.value}"
