"""The checker's facade: one model, one property, one result."""

from __future__ import annotations

import time

from veribattery.checker.pctl import property_answer
from veribattery.checker.result import CheckResult
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import Expr, Property


def check(dtmc: DTMC, prop: Property | Expr, *, states: bool = True) -> CheckResult:
    """Check *prop* on *dtmc* and report PRISM's answer (at the initial states, unless
    the property is a filter).

    With ``states=False`` only the answer is kept (:meth:`CheckResult.without_states`),
    and its certificate is made for the initial states alone where that is cheaper.

    Numeric results carry certified bounds (``result.lower``, ``result.upper``)
    and ``result.precise``; see :class:`CheckResult`.

    :param dtmc: the built model.
    :param prop: a property (constants substituted, property-file labels inlined),
        or a bare formula.
    :raises CheckError: when the property cannot be checked on this model, or a
        bounded operator (``P>=0.9 [..]``) cannot be decided at the precision reached.
    """
    prop = prop if isinstance(prop, Property) else Property(prop)
    start = time.perf_counter()
    answer = property_answer(dtmc, prop.formula, initial_only=not states)
    result = CheckResult.of_answer(prop, answer, time.perf_counter() - start)
    return result if states else result.without_states()
