"""The checker's facade: one model, one property, one result."""

from __future__ import annotations

import time

from veribattery._types import BoolArray
from veribattery.checker.formula import pctl
from veribattery.checker.formula.leaves import Result
from veribattery.checker.result import CheckResult, Keep, require_keep
from veribattery.checker.workspace import Workspace
from veribattery.errors import ArgumentError
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import Expr, Property


def check(dtmc: DTMC, prop: Property | Expr, *, keep: Keep = "states",
          workspace: Workspace | None = None) -> CheckResult:
    """Check *prop* on *dtmc* and report PRISM's answer (at the initial states, unless
    the property is a filter).

    With ``keep="answers"`` only the answer is kept (:meth:`CheckResult.without_states`),
    and its certificate is made for the initial states alone where that is cheaper.

    Numeric results carry certified bounds (``result.lower``, ``result.upper``)
    and ``result.precise``; see :class:`CheckResult`.

    :param dtmc: the built model.
    :param prop: a property (constants substituted, property-file labels inlined),
        or a bare formula.
    :param workspace: the caches to use and fill (graph searches, linear systems,
        results), shared with the other checks given it; None: a new one for this
        check alone.
    :raises CheckError: when the property cannot be checked on this model, or a
        bounded operator (``P>=0.9 [..]``) cannot be decided at the precision reached.
    :raises ArgumentError: for text instead of a parsed property, anything but a DTMC
        as *dtmc* (a model not built, or an MDP), or an unknown *keep*.
    """
    if not isinstance(dtmc, DTMC):
        raise ArgumentError.wrong_kind(
            "dtmc", dtmc, "a built DTMC", "veribattery.build_dtmc(veribattery.flatten_model("
            "model)); an MDP's properties are checked by veribattery.check_prism_file")
    if isinstance(prop, str):
        raise ArgumentError(f"check takes a parsed property, not the text {prop!r}: give "
                            f"veribattery.parse_property({prop!r})")
    require_keep(keep)
    prop = prop if isinstance(prop, Property) else Property(prop)
    workspace = Workspace() if workspace is None else workspace
    start = time.perf_counter()
    answer = pctl.property_answer(dtmc, workspace, prop.formula, keep=keep)
    result = CheckResult.of_answer(prop, answer, time.perf_counter() - start)
    return result if keep == "states" else result.without_states()


def values(dtmc: DTMC, formula: Expr, *, workspace: Workspace | None = None) -> Result:
    """Per-state value of *formula*: certified numbers for ``P=?``/``R=?``/``S=?``
    and expressions over them, booleans otherwise
    (:func:`~veribattery.checker.formula.pctl.values`).

    :param workspace: as for :func:`check`.
    """
    return pctl.values(dtmc, Workspace() if workspace is None else workspace, formula)


def state_set(dtmc: DTMC, expr: Expr, *, workspace: Workspace | None = None) -> BoolArray:
    """The states that satisfy the state formula *expr*, as a boolean mask
    (:func:`~veribattery.checker.formula.pctl.state_set`).

    :param workspace: as for :func:`check`.
    """
    return pctl.state_set(dtmc, Workspace() if workspace is None else workspace, expr)
