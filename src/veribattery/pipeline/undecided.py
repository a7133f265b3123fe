"""Bounds the certified float interval cannot decide, settled in exact arithmetic.

``P>=1/3 [ F s=1 ]`` when the value is exactly 1/3: no float interval, however
narrow, decides it. The float check reports such a property as an
:class:`~veribattery.checker.UndecidedResult`; it is then checked again on the
model built in exact rationals (DTMC or MDP alike), which decides it. Where the
model has no exact rational form (``sqrt``, ``exp``, an operator without an exact
kernel) the result stays undecided, with the reason -- never an input error.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, TypeVar

from veribattery.checker import CheckResult, UndecidedResult
from veribattery.errors import VeribatteryError
from veribattery.lang import Model, PropertiesFile, Property
from veribattery.lang.nodes import Value
from veribattery.pipeline.run import ModelCheckRun

if TYPE_CHECKING:
    from veribattery.pipeline.mdp import MdpCheckRun  # the MDP engine only for MDPs

__all__ = ["ExactCheck", "settle_undecided"]

Run = TypeVar("Run", ModelCheckRun, "MdpCheckRun")

#: Checks properties of a model in exact arithmetic: (model, properties, props file,
#: constants) to results, one per property.
ExactCheck = Callable[
    [Model, Sequence[Property], PropertiesFile | None, Mapping[str, Value | str] | None],
    Sequence[CheckResult],
]


def settle_undecided(
    run: Run,
    properties: Sequence[Property],
    exact_check: ExactCheck,
    model: Model,
    props_file: PropertiesFile | None,
    constants: Mapping[str, Value | str] | None,
) -> Run:
    """*run* with each undecided result checked again in exact arithmetic.

    :param properties: the properties as written, in the order of *run*'s results
        (their bounds are evaluated exactly: ``1/3``, not the double nearest it).
    :param exact_check: the exact check of the model's type.
    :return: *run* itself when nothing is undecided; else a copy with the settled
        results, a warning for each, and the exact checks' time in its ``check`` stage.
    """
    open_ = [i for i, r in enumerate(run.results) if isinstance(r, UndecidedResult)]
    if not open_:
        return run
    start = time.perf_counter()
    results = list(run.results)
    warnings: list[str] = []
    for i in open_:
        undecided = run.results[i]
        assert isinstance(undecided, UndecidedResult)
        name = undecided.property.name or undecided.property.text
        try:
            settled = exact_check(model, [properties[i]], props_file, constants)[0]
        except VeribatteryError as exc:
            reason = f"{undecided.reason}; not decidable in exact arithmetic: {exc}"
            results[i] = replace(undecided, reason=reason)
            warnings.append(f"{name}: undecided ({reason})")
            continue
        results[i] = settled
        warnings.append(f"{name}: decided in exact arithmetic (the certified interval "
                        "straddled the bound)")
    timings = dict(run.timings_s)
    timings["check"] = timings.get("check", 0.0) + time.perf_counter() - start
    return replace(run, results=tuple(results), timings_s=timings,
                   warnings=run.warnings + tuple(warnings))
