"""What a mission check reports: named values, requirements judged from certified
intervals or exact values, and the probability that the recharge cap cuts the mission."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from fractions import Fraction

from veribattery.checker import CheckResult
from veribattery.config import MissionConfig, Requirement, derive_parameters
from veribattery.lang import parse_property
from veribattery.lang.nodes import (
    BOUND_RELATIONS,
    Conditional,
    ConditionalReach,
    ProbOp,
    Property,
    RewardOp,
    Value,
)
from veribattery.pipeline import ModelCheckRun

__all__ = ["CAP_CONSEQUENCE", "RECHARGE_CAP", "RECHARGE_CAP_WARN_AT", "MissionReport",
           "RequirementOutcome", "is_conditional", "mission_report", "recharge_cap_message",
           "recharge_cap_property"]

#: The recharge-cap warning is given from this probability on: below it the cut cannot
#: change a printed (6 significant digit) result (model-spec.md, Battery ``oob`` row).
RECHARGE_CAP_WARN_AT = 1e-9

#: The name of the mission's internal property P[F rc=RC_MAX] (see
#: :func:`recharge_cap_property`): read by the report, never listed with the config's.
RECHARGE_CAP = "recharge_cap"


@dataclass(frozen=True, slots=True)
class RequirementOutcome:
    """A requirement and whether the checked value meets it."""

    requirement: Requirement
    value: Value
    holds: bool
    #: False when the certified interval straddles the bound (then *holds* is False).
    decided: bool = True

    def as_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        return {"requirement": str(self.requirement), "property": self.requirement.prop,
                "value": self.value, "holds": self.holds, "decided": self.decided}


@dataclass(frozen=True, slots=True)
class MissionReport:
    """The verification of one mission config: the run, named values, requirement outcomes."""

    # The caller's own input, left out of the repr so that the answers show.
    config: MissionConfig = field(repr=False)
    run: ModelCheckRun
    requirements: tuple[RequirementOutcome, ...]
    warnings: tuple[str, ...]
    #: P[F rc=RC_MAX]: the probability that the recharge cap cuts the mission (model-spec,
    #: ``oob`` row); always reported in machine-readable output, warned about from
    #: :data:`RECHARGE_CAP_WARN_AT` on.
    recharge_cap_probability: float

    @property
    def reused(self) -> bool:
        """True when an earlier config's state space was re-used (see
        :class:`~veribattery.mission.MissionSession`)."""
        return self.run.reused

    @property
    def values(self) -> dict[str, Value]:
        """Property name → value at the initial state, in config order."""
        return {r.property.name or r.property.text: r.value for r in self.run.results}

    @property
    def all_requirements_hold(self) -> bool:
        """True when every requirement holds (vacuously true without requirements)."""
        return all(outcome.holds for outcome in self.requirements)


def recharge_cap_property(cfg: MissionConfig) -> Property:
    """``P=? [ F rc=RC_MAX ]``, named :data:`RECHARGE_CAP`: the probability that the
    recharge cap cuts the mission (model-spec, ``oob`` row), an internal property of
    every mission check (0 without a check where no state reaches the cap)."""
    rc_max = derive_parameters(cfg).rc_max
    return replace(parse_property(f"P=? [ F rc={rc_max} ]"), name=RECHARGE_CAP)


def mission_report(cfg: MissionConfig, run: ModelCheckRun) -> MissionReport:
    """The report of a finished *run* of *cfg*, checked with its
    :func:`recharge_cap_property` as an internal property: requirements judged, the
    recharge cap's probability read and warned about."""
    results = {r.property.name: r for r in run.results}
    outcomes = tuple(_judge(req, results) for req in cfg.parsed_requirements)
    cap = float(run.internal_value(RECHARGE_CAP))
    return MissionReport(cfg, run, outcomes, run.warnings + _recharge_cap_warning(cap, cfg), cap)


def is_conditional(formula: object) -> bool:
    """Whether *formula* is a conditional (``||``) P or R query."""
    return isinstance(formula, ProbOp | RewardOp) and isinstance(
        formula.path, Conditional | ConditionalReach)

def _judge(requirement: Requirement,
           results: Mapping[str | None, CheckResult]) -> RequirementOutcome:
    """Decide *requirement* from the exact value or the certified interval, never from a
    rounded point value alone.

    With ``--exact`` the comparison is exact. Otherwise it holds only if it holds at
    both ends of ``[lower, upper]`` (the comparisons are monotone, so then everywhere
    between); it fails if it fails at both; otherwise it is undecided, which counts as
    not holding.
    """
    result = results[requirement.prop]
    value = result.value
    exact = getattr(result, "exact", None)
    if isinstance(exact, Fraction):
        return RequirementOutcome(requirement, value, BOUND_RELATIONS[requirement.op](
            exact, requirement.bound))
    if isinstance(value, bool) or math.isnan(value):
        return RequirementOutcome(requirement, value, False)
    ends = (value, value) if result.lower is None or result.upper is None else (
        result.lower, result.upper)
    verdicts = {requirement.holds(end) for end in ends}
    decided = len(verdicts) == 1
    return RequirementOutcome(requirement, value, decided and verdicts == {True}, decided)

def _recharge_cap_warning(probability: float, cfg: MissionConfig) -> tuple[str, ...]:
    """The spec's warning, only when the cut can change a printed result (P >= 1e-9)."""
    if probability < RECHARGE_CAP_WARN_AT:
        return ()
    return (recharge_cap_message(cfg.battery.max_recharges, probability),)


#: What reaching the cap means (model-spec: ``oob`` at s=5 with k < K, rc = RC_MAX): a
#: mission that reaches it may still finish on that battery, so P[F rc=RC_MAX], which the
#: spec has every run report, bounds the missions cut from above.
CAP_CONSEQUENCE = "a mission that needs another recharge then is cut (counted as a failure)"


def recharge_cap_message(rc_max: int, probability: float, where: str = "") -> str:
    """The recharge-cap warning text (*where*: the sweep points concerned, if any)."""
    return (
        f"the recharge cap battery.max_recharges={rc_max} is reached with probability "
        f"{probability:.6g}{where}; " + CAP_CONSEQUENCE
    )

