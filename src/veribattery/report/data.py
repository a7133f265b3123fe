"""The numbers a mission report shows, as plain frozen records.

Everything the page prints is decided here, from the library's own results (see
:mod:`veribattery.report.collect`): the template only lays these records out and
formats their numbers, and the figures only draw them. Records hold tuples, not
lists, so that a report cannot change once collected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from veribattery._types import FloatArray

if TYPE_CHECKING:
    from veribattery.report.sweep import SweepResults

__all__ = [
    "Battery",
    "ConsumptionRow",
    "DeadlineRow",
    "EstimateRow",
    "FailurePath",
    "Failures",
    "Farm",
    "GroupRow",
    "GroupTable",
    "MissionTime",
    "MonteCarlo",
    "PathStep",
    "Provenance",
    "Quantity",
    "ReportData",
    "RequirementRow",
    "Verdict",
    "json_number",
]


def json_number(value: float | bool | None) -> object:
    """A value as ``check --format json`` writes it: NaN as null, infinities as strings."""
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, float) and math.isinf(value):
        return "Infinity" if value > 0 else "-Infinity"
    return value


# ---------------------------------------------------------------------------
# The verdict
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Quantity:
    """One named result of the config, with its certified interval.

    :ivar label: how a reader calls it (``P(success)``), else the name.
    :ivar value: the value at the initial state (None: undefined, e.g. given an
        impossible success).
    :ivar lower: certified lower bound (None for a yes/no result).
    :ivar error: half the interval's width around *value*, at most.
    :ivar error_shown: the error reaches the 12th significant digit, so a table prints
        ``value ± error`` (as ``check`` does); otherwise every printed digit is certified.
    :ivar precise: the interval reached the default precision.
    :ivar conditional: an expectation given a condition (``||``).
    """

    name: str
    label: str
    formula: str
    value: float | bool | None
    lower: float | None
    upper: float | None
    error: float
    error_shown: bool
    precise: bool
    conditional: bool


@dataclass(frozen=True, slots=True)
class RequirementRow:
    """A requirement of the config and how it was decided.

    :ivar verdict: ``holds``, ``fails`` or ``undecided`` (the interval straddles the bound).
    """

    text: str
    prop: str
    value: float | bool | None
    lower: float | None
    upper: float | None
    verdict: str
    holds: bool
    decided: bool


@dataclass(frozen=True, slots=True)
class Verdict:
    """The answer first: requirements, headline values, and how sure they are.

    :ivar summary: one sentence a reviewer reads first.
    :ivar certification: the certification status in plain words.
    :ivar recharge_cap_probability: P[F rc=RC_MAX], as ``check`` reports it.
    :ivar timings_s: parse, build and check seconds, as ``check`` reports them.
    """

    summary: str
    requirements: tuple[RequirementRow, ...]
    quantities: tuple[Quantity, ...]
    states: int
    transitions: int
    all_hold: bool
    certification: str
    recharge_cap_probability: float
    timings_s: tuple[tuple[str, float], ...]
    warnings: tuple[str, ...]

    def check_json(self) -> dict[str, object]:
        """The document ``veribattery check --format json`` prints for the same config."""
        return {
            "model": {"states": self.states, "transitions": self.transitions},
            "results": {q.name: json_number(q.value) for q in self.quantities},
            "bounds": {q.name: [json_number(q.lower), json_number(q.upper)]
                       for q in self.quantities if q.lower is not None and q.upper is not None},
            "precise": {q.name: q.precise for q in self.quantities},
            "conditional": [q.name for q in self.quantities if q.conditional],
            "requirements": [
                {"requirement": r.text, "property": r.prop, "value": json_number(r.value),
                 "holds": r.holds, "decided": r.decided} for r in self.requirements
            ],
            "timings_s": {k: round(v, 6) for k, v in self.timings_s},
            "recharge_cap_probability": self.recharge_cap_probability,
        }


# ---------------------------------------------------------------------------
# The mission as a picture
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Farm:
    """The farm's grid and the route, as the model was rendered from them.

    :ivar route: the cells visited, in order (``[x, y]``).
    :ivar turbines: turbines inspected from each route cell.
    :ivar appointed: each turbine ``(tx, ty)`` and the cell it is inspected from.
    """

    cols: int
    rows: int
    spacing_m: float
    base: tuple[int, int]
    route_name: str
    route: tuple[tuple[int, int], ...]
    turbines: tuple[int, ...]
    appointed: tuple[tuple[tuple[int, int], tuple[int, int]], ...]

    @property
    def cells(self) -> tuple[int, int]:
        """Cells across and up."""
        return (self.cols - 1, self.rows - 1)


@dataclass(frozen=True, slots=True)
class ConsumptionRow:
    """Charge one action costs at one wind, by voltage level (low, medium, high), in Ah."""

    action: str
    wind: str
    ah: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class Battery:
    """The battery model: capacity over recharges, voltage levels, consumption.

    :ivar capacity_ah: the model's capacity after each number of recharges (its own
        ``cap`` formula, in Ah), index = recharges.
    :ivar level_high: SOC above which the voltage is high.
    :ivar level_low: SOC below which the voltage is low.
    :ivar safe_t: the reserve the drone keeps (strategy ``safe_t``, a fraction of capacity).
    """

    model: str
    new_capacity_ah: float
    resolution_ah: float
    fade_per_recharge: float
    max_recharges: int
    capacity_ah: tuple[float, ...]
    level_high: float
    level_low: float
    safe_t: float
    p_wind_change: float
    consumption: tuple[ConsumptionRow, ...]
    consumption_source: str
    times_min: tuple[tuple[str, float], ...]


# ---------------------------------------------------------------------------
# Where failures come from
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class GroupRow:
    """One group of the breakdown: its key values, probability and share of P(failure)."""

    values: tuple[object, ...]
    probability: float
    share: float


@dataclass(frozen=True, slots=True)
class GroupTable:
    """P(failure) summed by *keys*, most probable first (every group: they sum to it)."""

    keys: tuple[str, ...]
    title: str
    rows: tuple[GroupRow, ...]

    def records(self) -> list[dict[str, object]]:
        """The grouping as ``explain --format json`` lists it."""
        return [{**dict(zip(self.keys, row.values, strict=True)), "probability": row.probability}
                for row in self.rows]


@dataclass(frozen=True, slots=True)
class PathStep:
    """One step of a failure path, as the paper's Fig. 7 reads it.

    :ivar minutes: mission time before this step (the ``mt`` reward so far).
    :ivar action: the action taken from this state (empty at the end).
    :ivar event: the step in words.
    """

    step: int
    minutes: float
    action: str
    state: str
    cell: str
    turbines: str
    wind: str
    charge_ah: float
    soc: float
    level: str
    rc: int
    event: str


@dataclass(frozen=True, slots=True)
class FailurePath:
    """One of the most probable failure paths.

    :ivar probability_text: the probability to 6 digits, also below the float range.
    :ivar sortie_start: index in *steps* of the final sortie's first step (after the
        last recharge).
    :ivar folded: the recharge trips before the final sortie in one line, if any.
    :ivar story: what happens, in one sentence.
    """

    rank: int
    probability: float
    probability_text: str
    steps: tuple[PathStep, ...]
    sortie_start: int
    folded: str
    story: str

    @property
    def sortie(self) -> tuple[PathStep, ...]:
        """The steps of the final sortie, the failing step included."""
        return self.steps[self.sortie_start:]


@dataclass(frozen=True, slots=True)
class Failures:
    """The exact breakdown of P(failure) and the most probable failure paths.

    :ivar entering_states: states failure is entered from (the breakdown sums over them).
    :ivar by_cell: P(failure) per farm cell ``(x, y)`` (cells never failed from omitted).
    :ivar after_route: P(failure) once every cell is done, on the way home (route cell
        ``done``: on no cell of the map).
    """

    probability: float
    entering_states: int
    tables: tuple[GroupTable, ...]
    by_cell: tuple[tuple[tuple[int, int], float], ...]
    after_route: float
    paths: tuple[FailurePath, ...]

    def table(self, *keys: str) -> GroupTable | None:
        """The grouping by exactly *keys*, if collected."""
        return next((t for t in self.tables if t.keys == keys), None)


# ---------------------------------------------------------------------------
# Time
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class DeadlineRow:
    """P(success within a deadline), and P(the mission is over by then, either way)."""

    text: str
    minutes: float
    working_days: float
    p_success: float
    p_over: float


@dataclass(frozen=True, slots=True)
class MissionTime:
    """The distribution of mission time (``mt``, minutes), exact level by level.

    :ivar minutes: the reward levels; *success_cdf*/*failure_cdf* are
        P(success/failure with at most that time) at each.
    :ivar pending: probability still under way after the last level (the cut-off).
    """

    p_success: float
    p_failure: float
    expected_given_success: float
    quantiles: tuple[tuple[float, float], ...]
    deadlines: tuple[DeadlineRow, ...]
    working_day_minutes: float
    levels: int
    last_level: float
    pending: float
    coverage: float
    minutes: FloatArray = field(repr=False)
    success_cdf: FloatArray = field(repr=False)
    failure_cdf: FloatArray = field(repr=False)

    def distribution_json(self) -> dict[str, object]:
        """The numbers ``veribattery distribution --format json`` prints."""
        return {
            "reward": "mt", "p_success": self.p_success, "p_failure": self.p_failure,
            "expected_given_success": json_number(self.expected_given_success),
            "quantiles": {str(q): v for q, v in self.quantiles},
            "deadlines": [{"deadline": d.text, "value": d.minutes,
                           "p_success_within": d.p_success} for d in self.deadlines],
            "levels": self.levels, "last_level": self.last_level, "pending": self.pending,
        }


# ---------------------------------------------------------------------------
# Monte-Carlo
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class EstimateRow:
    """A Monte-Carlo estimate beside the exact value.

    :ivar agrees: the exact value lies inside the estimate's 99.9 % interval.
    """

    name: str
    label: str
    exact: float | None
    estimate: float
    ci95: tuple[float, float]
    runs: int
    undecided: int
    agrees: bool


@dataclass(frozen=True, slots=True)
class MonteCarlo:
    """The simulation: runs, seed, and one estimate per simulated property.

    :ivar skipped: the properties not simulated, each with the reason.
    :ivar warnings: estimates that disagree with the exact value, or undecided runs.
    """

    runs: int
    seed: int
    max_steps: int
    longest: int
    estimates: tuple[EstimateRow, ...]
    skipped: tuple[str, ...]
    warnings: tuple[str, ...]


# ---------------------------------------------------------------------------
# Reproducibility, and the whole report
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Provenance:
    """What a reviewer needs to re-run the report, in PRISM or Storm too.

    :ivar version: veribattery's version and the digest of its PRISM templates.
    :ivar timings_s: seconds per stage of making this report.
    """

    version: str
    command_line: str
    config_name: str
    config_yaml: str
    config_sha256: str
    states: int
    transitions: int
    seed: int | None
    generated_utc: str
    timings_s: tuple[tuple[str, float], ...]
    model_prism: str
    properties_props: str
    storm_only_props: str


@dataclass(frozen=True, slots=True)
class ReportData:
    """Every number of one mission report. *simulation* and *sweep* are optional.

    :ivar settings: the ``--set`` overrides of the config file (*title*).
    """

    title: str
    settings: tuple[str, ...]
    verdict: Verdict
    farm: Farm
    battery: Battery
    failures: Failures
    time: MissionTime
    simulation: MonteCarlo | None
    sweep: SweepResults | None
    provenance: Provenance
