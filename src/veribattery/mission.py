"""The mission facade: config → rendered PRISM text → the same pipeline as any user file."""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from veribattery.checker import check
from veribattery.config import MissionConfig, Requirement, config_to_yaml, derive_parameters
from veribattery.errors import VeribatteryError
from veribattery.lang import parse_model, parse_properties, parse_property
from veribattery.lang.nodes import Value
from veribattery.pipeline import ModelCheckRun, ProgressCallback, check_model

MODEL_FILE = "model.prism"
PROPERTIES_FILE = "properties.props"
CONFIG_FILE = "config.resolved.yaml"

#: The recharge-cap warning is given from this probability on: below it the cut cannot
#: change a printed (6 significant digit) result (model-spec.md, Battery ``oob`` row).
RECHARGE_CAP_WARN_AT = 1e-9


@dataclass(frozen=True, slots=True)
class RequirementOutcome:
    """A requirement and whether the checked value meets it."""

    requirement: Requirement
    value: Value
    holds: bool

    def as_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        return {"requirement": str(self.requirement), "property": self.requirement.prop,
                "value": self.value, "holds": self.holds}


@dataclass(frozen=True, slots=True)
class MissionReport:
    """The verification of one mission config: the run, named values, requirement outcomes."""

    config: MissionConfig
    run: ModelCheckRun
    requirements: tuple[RequirementOutcome, ...]
    warnings: tuple[str, ...]
    #: P[F rc=RC_MAX]: the probability that the recharge cap cuts the mission (model-spec,
    #: ``oob`` row); always reported in machine-readable output, warned about from
    #: :data:`RECHARGE_CAP_WARN_AT` on.
    recharge_cap_probability: float

    @property
    def values(self) -> dict[str, Value]:
        """Property name → value at the initial state, in config order."""
        return {r.property.name or r.property.text: r.value for r in self.run.results}

    @property
    def all_requirements_hold(self) -> bool:
        """True when every requirement holds (vacuously true without requirements)."""
        return all(outcome.holds for outcome in self.requirements)


@dataclass(frozen=True, slots=True)
class MissionFiles:
    """The emitted texts: the PRISM model, its properties, and the resolved config."""

    model: str
    properties: str
    config: str

    def as_mapping(self) -> Mapping[str, str]:
        """File name → text."""
        return {MODEL_FILE: self.model, PROPERTIES_FILE: self.properties, CONFIG_FILE: self.config}


def mission_files(cfg: MissionConfig) -> MissionFiles:
    """Render the model and properties of *cfg* (imported late: rendering needs Jinja)."""
    from veribattery.render import render_model, render_properties

    return MissionFiles(render_model(cfg), render_properties(cfg), config_to_yaml(cfg))


def check_mission(cfg: MissionConfig, *, progress: ProgressCallback | None = None) -> MissionReport:
    """Render *cfg*, parse and check the text like any PRISM file, and judge the requirements."""
    files = mission_files(cfg)
    model = parse_model(files.model, name=MODEL_FILE)
    props = parse_properties(files.properties, name=PROPERTIES_FILE)
    run = check_model(model, props.properties, props_file=props, progress=progress)
    return mission_report(cfg, run)


def mission_report(cfg: MissionConfig, run: ModelCheckRun) -> MissionReport:
    """The report of a finished *run* of *cfg*: requirements judged, recharge cap measured."""
    values = {r.property.name: r.value for r in run.results}
    outcomes = tuple(_judge(req, values) for req in cfg.parsed_requirements)
    cap = recharge_cap_probability(run, cfg)
    return MissionReport(cfg, run, outcomes, run.warnings + _recharge_cap_warning(cap, cfg), cap)


class MissionChecker:
    """Checks mission configs one after another, for sweeps.

    The seam for structure reuse: a checker may keep the state space of the configs
    it has seen and, when a new config changes only transition probabilities,
    re-evaluate and re-solve instead of rebuilding. Configs with equal
    :func:`reuse_key` are the ones that can share a state space; this version
    shares none and builds every config afresh.
    """

    def check(self, cfg: MissionConfig) -> MissionReport:
        """Check *cfg* as :func:`check_mission` does."""
        return check_mission(cfg)


def reuse_key(cfg: MissionConfig) -> str | None:
    """A key equal for configs that can share one state space (None: this one shares none)."""
    return None


def _judge(requirement: Requirement, values: Mapping[str | None, Value]) -> RequirementOutcome:
    value = values[requirement.prop]
    holds = not isinstance(value, bool) and not math.isnan(value) and requirement.holds(value)
    return RequirementOutcome(requirement, value, holds)


def recharge_cap_probability(run: ModelCheckRun, cfg: MissionConfig) -> float:
    """P[F rc=RC_MAX] in *run*'s DTMC (0 without computing when no state reaches the cap)."""
    rc_max = derive_parameters(cfg).rc_max
    if run.dtmc.column("rc").max() < rc_max:
        return 0.0
    return float(check(run.dtmc, parse_property(f"P=? [ F rc={rc_max} ]")).value)


def _recharge_cap_warning(probability: float, cfg: MissionConfig) -> tuple[str, ...]:
    """The spec's warning, only when the cut can change a printed result (P >= 1e-9)."""
    if probability < RECHARGE_CAP_WARN_AT:
        return ()
    return (recharge_cap_message(cfg.battery.max_recharges, probability),)


def recharge_cap_message(rc_max: int, probability: float, where: str = "") -> str:
    """The recharge-cap warning text (*where*: the sweep points concerned, if any)."""
    return (
        f"the recharge cap battery.max_recharges={rc_max} is reached with probability "
        f"{probability:.6g}{where}; those missions are cut (counted as failures)"
    )


def write_files(files: MissionFiles, directory: Path, *, force: bool = False) -> tuple[Path, ...]:
    """Write the emitted files into *directory*, all or nothing.

    Existing files are never overwritten unless *force*; each file is written to a
    temporary name first and renamed, so a failure leaves no partial output.
    """
    targets = {directory / name: text for name, text in files.as_mapping().items()}
    clashes = [str(p) for p in targets if p.exists()]
    if clashes and not force:
        raise VeribatteryError(
            f"{', '.join(clashes)} already exist(s); use --force to overwrite, or pick another -o"
        )
    directory.mkdir(parents=True, exist_ok=True)
    staged: list[tuple[Path, Path]] = []
    try:
        for path, text in targets.items():
            staged.append((_stage(directory, text), path))
    except OSError:
        for temporary, _ in staged:
            temporary.unlink(missing_ok=True)
        raise
    for temporary, path in staged:
        os.replace(temporary, path)
    return tuple(targets)


def _stage(directory: Path, text: str) -> Path:
    handle, name = tempfile.mkstemp(dir=directory, prefix=".veribattery-", suffix=".tmp")
    with os.fdopen(handle, "w", encoding="utf-8") as stream:
        stream.write(text)
    return Path(name)
