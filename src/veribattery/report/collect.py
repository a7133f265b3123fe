"""Collect a report's numbers: the mission is built and checked once, and every analysis
runs on that one DTMC.

``check`` (:func:`~veribattery.mission.check_mission` with ``keep="answers"``)
builds and checks the chain; its DTMC is handed on to ``explain``'s breakdown and
paths, ``distribution``'s CDF and ``simulate``'s runs, so the state space is explored
once. (The check keeps its state table in a narrow integer type; the analyses
evaluate the model's formulas on whole rows, so they get it widened back to int64:
a copy of the table, not a second build.)
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from datetime import UTC, datetime

import numpy as np

from veribattery.analyses.distribution import Deadline
from veribattery.analyses.mission_view import MissionModel, MissionView
from veribattery.config import MissionConfig
from veribattery.explore.dtmc import DTMC
from veribattery.lang import flatten_model, parse_model
from veribattery.mission import MODEL_FILE, MissionFiles, check_mission, mission_files
from veribattery.pipeline import ProgressCallback, Stopwatch
from veribattery.report.data import Provenance, ReportData
from veribattery.report.failures import explain_failures, failures_of
from veribattery.report.montecarlo import monte_carlo
from veribattery.report.picture import battery_picture, farm_picture
from veribattery.report.sweep import SweepResults
from veribattery.report.timing import mission_time
from veribattery.report.verdict import make_verdict
from veribattery.sweep.fingerprint import model_version

__all__ = ["ReportOptions", "collect_report"]

#: Called with one short line per stage (the CLI prints them on stderr).
Notes = Callable[[str], None]


@dataclass(frozen=True, slots=True)
class ReportOptions:
    """What to put in a report beyond the check, with the CLI's defaults.

    :ivar runs: simulated runs (0: no Monte-Carlo section).
    :ivar seed: the simulation's seed.
    :ivar max_steps: steps after which an undecided run stops.
    :ivar top: most probable failure paths to show.
    :ivar deadlines: P(success within D) for each (empty: whole working days).
    :ivar working_day_minutes: minutes in a working day ``d``.
    :ivar coverage: the mission-time distribution is computed until this share.
    :ivar title: the report's title (the config's name).
    :ivar settings: the ``--set KEY=VALUE`` overrides the config was loaded with, shown
        under the title (two reports of one file differ by them).
    :ivar command_line: the command that made the report, for reproducibility.
    """

    runs: int = 1000
    seed: int = 0
    max_steps: int = 100_000
    top: int = 3
    deadlines: tuple[Deadline, ...] = ()
    working_day_minutes: float = 480.0
    coverage: float = 0.999
    title: str = "mission"
    settings: tuple[str, ...] = ()
    command_line: str = ""


def collect_report(cfg: MissionConfig, options: ReportOptions, *,
                   sweep: SweepResults | None = None,
                   progress: ProgressCallback | None = None,
                   notes: Notes | None = None) -> ReportData:
    """Check *cfg* and run every analysis of the report on its DTMC.

    :param sweep: a sweep's results already matched to *cfg* (:func:`read_sweep`).
    :param progress: called while the state space is explored.
    :raises VeribatteryError: as the check and the analyses raise it.
    """
    say = notes or (lambda _: None)
    clock = Stopwatch()
    with clock.stage("check"):
        say("checking the mission (build and model check)")
        report = check_mission(cfg, progress=progress, keep="answers")
        files = mission_files(cfg)
        mission = _mission(cfg, files, report.run.dtmc)
    view = MissionView(mission)
    with clock.stage("explain"):
        say(f"explaining failures (breakdown and {options.top} most probable paths)")
        failures = failures_of(view, explain_failures(view, options.top))
    with clock.stage("distribution"):
        say("computing the mission-time distribution")
        timing = mission_time(mission.dtmc, options.deadlines, options.working_day_minutes,
                              options.coverage, report.run.workspace)
    simulation = None
    if options.runs > 0:
        with clock.stage("simulate"):
            say(f"simulating {options.runs:,} runs (seed {options.seed})")
            simulation = monte_carlo(report.run, mission.dtmc, runs=options.runs,
                                     seed=options.seed, max_steps=options.max_steps)
    provenance = _provenance(options, files, mission.dtmc, clock.seconds)
    return ReportData(options.title, options.settings, make_verdict(report), farm_picture(mission),
                      battery_picture(mission), failures, timing, simulation, sweep, provenance)


def _mission(cfg: MissionConfig, files: MissionFiles, dtmc: DTMC) -> MissionModel:
    """The checked DTMC as the analyses need it: with its flat model, states as int64."""
    flat = flatten_model(parse_model(files.model, name=MODEL_FILE))
    wide = replace(dtmc, states=dtmc.states.astype(np.int64, copy=False))
    return MissionModel(cfg, flat, wide)


def _provenance(options: ReportOptions, files: MissionFiles, dtmc: DTMC,
                seconds: dict[str, float]) -> Provenance:
    return Provenance(
        version=model_version(), command_line=options.command_line, config_name=options.title,
        config_yaml=files.config,
        config_sha256=hashlib.sha256(files.config.encode("utf-8")).hexdigest(),
        states=dtmc.num_states, transitions=dtmc.num_transitions,
        seed=options.seed if options.runs > 0 else None,
        generated_utc=datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        timings_s=tuple(seconds.items()), model_prism=files.model,
        properties_props=files.properties, storm_only_props=files.storm_only,
    )

