"""``veribattery simulate`` and ``prism --simulate``: Monte-Carlo estimates of a
model's properties, beside the exact values."""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import click

from veribattery.cli.analysis_options import (
    MOST_RUNS,
    counted,
    induced_mission,
    strategy_option,
)
from veribattery.cli.files import (
    CSV_SUFFIXES,
    OnceOption,
    PathParam,
    check_output_file,
    typed_name,
)
from veribattery.cli.output import (
    build_progress,
    check_modes,
    format_value,
    json_value,
    out,
    print_warnings,
    print_written,
    set_option,
    user_errors,
)
from veribattery.cli.tables import print_table

if TYPE_CHECKING:
    from veribattery.analyses.simulate import Simulation
    from veribattery.config import MissionConfig
    from veribattery.explore import DTMC
    from veribattery.lang import FlatModel
    from veribattery.lang.nodes import Value
    from veribattery.pipeline import ModelCheckRun

__all__ = ["prism_simulate", "simulate_command", "simulation_options"]


def simulation_options(function: Callable[..., None]) -> Callable[..., None]:
    """The sampling options of ``simulate`` and ``prism --simulate``: seed, steps, paths."""
    for option in reversed((
        click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
                     help="Random seed (a non-negative integer)."),
        click.option("--max-steps", default=100_000, show_default=True,
                     callback=counted("--max-steps"),
                     help="Steps after which an undecided run stops (and is reported)."),
        click.option("-o", "--output", "--paths", "paths_file", cls=OnceOption,
                     type=PathParam(path_type=Path),
                     help="Write sampled paths here as CSV (PRISM simulator columns; "
                     "--paths: the old name)."),
        click.option("--path-count", default=10, show_default=True,
                     callback=counted("--path-count"), help="How many runs -o writes."),
        click.option("--force", is_flag=True, help="Overwrite existing output files."),
    )):
        function = option(function)
    return function


@click.command("simulate", short_help="Monte-Carlo estimates beside the exact values.")
@click.argument("config", type=PathParam(path_type=Path))
@set_option
@click.option("--runs", required=True, type=int, callback=counted("--runs", MOST_RUNS),
              help="Number of simulated runs.")
@simulation_options
@click.option("--format", "output_format", type=click.Choice(["table", "json", "csv"]),
              default="table", show_default=True, help="Output format.")
@strategy_option
def simulate_command(config: Path, overrides: tuple[str, ...], runs: int, seed: int,
                     max_steps: int, paths_file: Path | None, path_count: int, force: bool,
                     output_format: str, strategy: str) -> None:
    """Monte-Carlo estimates of the mission's named results, beside the exact values."""
    from veribattery.config import load_config
    from veribattery.mission import check_mission

    with user_errors():
        check_modes({"-o": (paths_file is not None, ("path_count",))})
        check_output_file(paths_file, typed_name("paths_file", "-o"), force=force,
                          suffixes=CSV_SUFFIXES)
        cfg = load_config(config, overrides)
        record = path_count if paths_file else 0
        if strategy != "bs1":
            _simulate_strategy(cfg, strategy, (runs, seed, max_steps, record), paths_file,
                               output_format)
            return
        with build_progress() as progress:
            report = check_mission(cfg, progress=progress)
        flat = _mission_flat(cfg) if paths_file is not None else None
        simulation = _simulate_run(report.run, runs, seed, max_steps, record)
        if paths_file is not None:
            _write_simulated_paths(paths_file, report.run.dtmc, simulation, flat)
    print_warnings(report.warnings)
    _show_simulation(simulation, output_format)


def _simulate_strategy(cfg: MissionConfig, strategy: str, sampling: tuple[int, int, int, int],
                       paths_file: Path | None, output_format: str) -> None:
    """``simulate --strategy optimal|FILE``: synthesize's three values of the strategy,
    estimated on the DTMC it induces, beside the exact values.

    :param sampling: runs, seed, max steps, and how many runs to record.
    """
    from veribattery.analyses.simulate import simulate

    runs, seed, max_steps, record = sampling
    with build_progress() as progress:
        induced = induced_mission(cfg, strategy, progress)
    simulation = simulate(induced.dtmc, induced.properties, runs=runs, seed=seed,
                          max_steps=max_steps, exact=induced.values, record=record)
    if paths_file is not None:
        _write_simulated_paths(paths_file, induced.dtmc, simulation, induced.flat)
    _show_simulation(simulation, output_format)


def _mission_flat(cfg: MissionConfig) -> FlatModel:
    from veribattery.lang import flatten_model, parse_model
    from veribattery.mission import MODEL_FILE, mission_files

    return flatten_model(parse_model(mission_files(cfg).model, name=MODEL_FILE))


def _simulate_run(run: ModelCheckRun, runs: int, seed: int, max_steps: int,
                  record: int) -> Simulation:
    from veribattery.analyses.simulate import simulate

    exact: dict[str, float] = {}
    for r in run.results:
        if isinstance(r.value, float):
            exact[r.property.name or r.property.text] = r.value
    return simulate(run.dtmc, [r.property for r in run.results], runs=runs, seed=seed,
                    max_steps=max_steps, exact=exact, record=record)


def _write_simulated_paths(path: Path, dtmc: DTMC, simulation: Simulation,
                           flat: FlatModel | None) -> None:
    from veribattery.analyses.actions import action_labeller
    from veribattery.analyses.csvout import write_csv
    from veribattery.analyses.simulate import path_table

    labeller = action_labeller(flat) if flat is not None else None
    header, rows = path_table(dtmc, simulation.paths, labeller)
    write_csv(path, header, rows)
    print_written(path)


def _show_simulation(simulation: Simulation, output_format: str) -> None:
    print_warnings(simulation.warnings())
    if output_format == "json":
        click.echo(json.dumps(_simulation_json(simulation)))
        return
    if output_format == "csv":
        _simulation_csv(simulation)
        return
    rows = []
    for e in simulation.estimates:
        exact = format_value(e.exact) if e.exact is not None else "-"
        estimate = f"{e.estimate:.6g}" if e.runs else "-"  # every run undecided: no nan
        ci = f"[{e.ci95[0]:.6g}, {e.ci95[1]:.6g}]" if e.runs else "-"
        runs = f"{e.runs:,}" + (f" ({e.undecided:,} undecided)" if e.undecided else "")
        rows.append((e.name, exact, estimate, ci, runs))
    print_table(("property", "exact", "estimate", "95% CI", "runs"), rows)
    out.print(f"{simulation.runs:,} runs, seed {simulation.seed}, "
              f"longest {simulation.steps:,} steps", style="dim", markup=False)


def _simulation_csv(simulation: Simulation) -> None:
    """``property,value,estimate,ci95_low,ci95_high,runs,undecided`` rows, full precision."""
    import csv
    import sys

    writer = csv.writer(sys.stdout, lineterminator="\n")
    writer.writerow(["property", "value", "estimate", "ci95_low", "ci95_high", "runs",
                     "undecided"])
    for e in simulation.estimates:
        writer.writerow([e.name, "" if e.exact is None else repr(e.exact),
                         *("" if math.isnan(x) else repr(x) for x in (e.estimate, *e.ci95)),
                         e.runs, e.undecided])


def _number(value: float | None) -> object:
    """A JSON number: infinities as strings (as ``check`` does), NaN (no decided run) as null."""
    return None if value is None or math.isnan(value) else json_value(value)


def _simulation_json(simulation: Simulation) -> dict[str, object]:
    return {
        "runs": simulation.runs,
        "seed": simulation.seed,
        "max_steps": simulation.max_steps,
        "results": {
            e.name: {"estimate": _number(e.estimate),
                     "ci95": [_number(e.ci95[0]), _number(e.ci95[1])],
                     "runs": e.runs, "undecided": e.undecided,
                     "value": _number(e.exact)}
            for e in simulation.estimates
        },
        "skipped": list(simulation.skipped),
    }



def prism_simulate(run: ModelCheckRun, model: Path, constants: Mapping[str, Value | str],
                   runs: int, *, seed: int, max_steps: int, paths_file: Path | None,
                   path_count: int, output_format: str) -> None:
    """``prism MODEL --simulate N``: estimates of the checked properties."""
    from veribattery.lang import flatten_model, parse_model

    with user_errors():
        simulation = _simulate_run(run, runs, seed, max_steps, path_count if paths_file else 0)
        if paths_file is not None:
            flat = flatten_model(parse_model(model), constants)
            _write_simulated_paths(paths_file, run.dtmc, simulation, flat)
    _show_simulation(simulation, output_format)
