"""The checker's facade: one model, one property, one result."""

from __future__ import annotations

import time

from veribattery.checker.pctl import property_answer
from veribattery.checker.result import CheckResult
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import Expr, Property


def check(dtmc: DTMC, prop: Property | Expr) -> CheckResult:
    """Check *prop* on *dtmc* and report PRISM's answer (at the initial states, unless
    the property is a filter).

    :param dtmc: the built model.
    :param prop: a property (constants substituted, property-file labels inlined),
        or a bare formula.
    :raises CheckError: when the property cannot be checked on this model.
    """
    prop = prop if isinstance(prop, Property) else Property(prop)
    start = time.perf_counter()
    answer = property_answer(dtmc, prop.formula)
    value, spread = answer.value, None
    if isinstance(value, tuple):
        spread = None if value[0] == value[1] else value
        value = value[0]
    if value is None:  # pragma: no cover - the default filter always gives a value
        raise AssertionError("no answer")
    number = value if isinstance(value, bool) else float(value)
    return CheckResult(prop, answer.values, number, time.perf_counter() - start, spread,
                       answer.printed)
