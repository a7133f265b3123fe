"""The verdict: the config's requirements and named results, from the same check as ``check``.

The values, intervals and requirement outcomes are those of
:func:`veribattery.mission.check_mission` with ``keep="answers"``, the call
``veribattery check`` makes, so the page and ``check --format json`` cannot differ.
"""

from __future__ import annotations

import math

from veribattery.checker import CheckResult
from veribattery.checker.certify.bounds import ABSOLUTE_PRECISION, RELATIVE_PRECISION
from veribattery.mission import MissionReport, RequirementOutcome, is_conditional
from veribattery.report.data import Quantity, RequirementRow, Verdict

__all__ = ["LABELS", "TABLE_DIGITS", "label", "make_verdict"]

#: Significant digits a value is printed with (as ``check``'s tables).
TABLE_DIGITS = 12

#: How a reader calls the default properties (times in minutes).
LABELS = {
    "p_success": "P(success)",
    "exp_mission_time": "E[mission time]",
    "exp_recharges": "E[recharges]",
    "exp_mission_time_given_success": "E[mission time | success]",
    "exp_recharges_given_success": "E[recharges | success]",
}


def label(name: str) -> str:
    """A property's reader-facing name: :data:`LABELS`, else the config's name."""
    return LABELS.get(name, name)


def make_verdict(report: MissionReport) -> Verdict:
    """The verdict of a finished check (``check_mission(cfg, keep="answers")``)."""
    dtmc = report.run.dtmc
    quantities = tuple(_quantity(r) for r in report.run.results)
    requirements = tuple(_requirement(o, report) for o in report.requirements)
    return Verdict(
        summary=_summary(requirements),
        requirements=requirements,
        quantities=quantities,
        states=dtmc.num_states,
        transitions=dtmc.num_transitions,
        all_hold=report.all_requirements_hold,
        certification=_certification(quantities, dtmc.num_states, dtmc.num_transitions),
        recharge_cap_probability=report.recharge_cap_probability,
        timings_s=tuple(report.run.timings_s.items()),
        warnings=report.warnings,
    )


def _quantity(result: CheckResult) -> Quantity:
    name = result.property.name or result.property.text
    value = None if isinstance(result.value, float) and math.isnan(result.value) else result.value
    return Quantity(name, label(name), result.property.text, value, result.lower, result.upper,
                    result.error, _error_shows(value, result.error), result.precise,
                    is_conditional(result.property.formula))


def _error_shows(value: float | bool | None, error: float) -> bool:
    """Whether *error* reaches half a unit in the last of :data:`TABLE_DIGITS` significant
    digits of *value* (``check``'s rule for printing ``± error``)."""
    if not isinstance(value, float) or isinstance(value, bool) or not math.isfinite(value):
        return False
    if error <= 0:
        return False
    if math.isinf(error) or value == 0:
        return True
    return error >= 0.5 * 10.0 ** (math.floor(math.log10(abs(value))) - TABLE_DIGITS + 1)


def _requirement(outcome: RequirementOutcome, report: MissionReport) -> RequirementRow:
    prop = outcome.requirement.prop
    result = next(r for r in report.run.results if r.property.name == prop)
    verdict = "undecided" if not outcome.decided else "holds" if outcome.holds else "fails"
    value = outcome.value
    shown = None if isinstance(value, float) and math.isnan(value) else value
    return RequirementRow(str(outcome.requirement), prop, shown, result.lower, result.upper,
                          verdict, outcome.holds, outcome.decided)


def _summary(requirements: tuple[RequirementRow, ...]) -> str:
    """One sentence: no requirement, all hold, or which fail or stay undecided."""
    if not requirements:
        return ("This config states no requirement, so there is no pass/fail verdict: "
                "its values and their certified intervals follow.")
    total = len(requirements)
    bad = [r for r in requirements if r.verdict != "holds"]
    if not bad:
        return ("The requirement holds." if total == 1 else
                f"All {total} requirements hold.") + " Each was decided on its whole " \
            "certified interval."
    listed = "; ".join(f"{r.text} {_VERDICT_WORDS[r.verdict]}" for r in bad)
    if total == 1:
        return f"The mission is not shown safe: {listed}."
    return f"The mission is not shown safe: {len(bad)} of {total} requirements do not hold " \
        f"({listed})."


#: A requirement's verdict in a sentence.
_VERDICT_WORDS = {"holds": "holds", "fails": "fails",
                  "undecided": "is undecided (its certified interval straddles the bound)"}


def _certification(quantities: tuple[Quantity, ...], states: int, transitions: int) -> str:
    """How the numbers were obtained, and whether every one reached the default precision."""
    method = (f"Exact model checking, not sampling: every reachable state of the model was "
              f"built ({states:,} states, {transitions:,} transitions) and each value was "
              "solved for from linear equations. Each value comes with a certified interval "
              "that provably contains the exact value of the model as built, rounding "
              "included; a requirement holds only when its whole interval meets it.")
    undefined = [q.label for q in quantities if q.value is None]
    loose = [q.label for q in quantities if q.value is not None and not q.precise]
    numeric = [q for q in quantities if q.lower is not None]
    precision = (f"{RELATIVE_PRECISION:g} relative or {ABSOLUTE_PRECISION:g} absolute")
    if not loose:
        status = (f" All {len(numeric)} numeric values are certified to the default precision "
                  f"(an interval no wider than {precision}).")
    else:
        status = (f" Not certified to the default precision ({precision}): "
                  f"{', '.join(loose)}; their intervals are wider, and shown as computed.")
    if undefined:
        status += f" Undefined (no value on this model): {', '.join(undefined)}."
    return method + status
