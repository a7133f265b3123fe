"""``veribattery explain``, ``veribattery simulate``, and ``prism --explain/--simulate``.

Where failures come from (the exact breakdown and the most probable paths), and
Monte-Carlo estimates beside the exact values.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import click

from veribattery.cli.files import CSV_SUFFIXES, PathParam, check_output_file
from veribattery.cli.output import (
    build_progress,
    fail,
    format_value,
    json_value,
    out,
    print_dim,
    print_warnings,
    print_written,
    set_option,
    user_errors,
)
from veribattery.cli.tables import fit_text, print_table
from veribattery.errors import VeribatteryError

if TYPE_CHECKING:
    from veribattery._types import IntArray
    from veribattery.analyses.explain import Explanation, Grouping
    from veribattery.analyses.mission_view import MissionView
    from veribattery.analyses.simulate import Simulation
    from veribattery.config import MissionConfig
    from veribattery.explore import DTMC
    from veribattery.lang import FlatModel
    from veribattery.lang.nodes import Value
    from veribattery.pipeline import ModelCheckRun, ProgressCallback
    from veribattery.synthesis.induced_dtmc import InducedMission

#: Rows shown per grouping in the table output (JSON has them all).
GROUP_ROWS = 8
#: Width of the text bar beside each group's probability.
BAR_WIDTH = 20
#: Columns of the mission's path table: (header, step-row key).
MISSION_COLUMNS = (
    ("step", "step"), ("action", "action"), ("drone", "state"), ("cell", "cell"),
    ("turbines", "turbines"), ("wind", "wind"), ("charge", "charge"), ("SOC", "soc_text"),
    ("level", "level"), ("rc", "rc"),
)
#: Columns of ``explain --csv``.
CSV_COLUMNS = ("path", "probability", "step", "action", "state", "s", "k", "j", "x", "y",
               "wsp", "b", "rc", "charge_ah", "soc", "level")


#: The most simulated runs asked for at once (each keeps a few bytes of state; numpy cannot
#: size arrays past 2^63), and the most paths shown (10,000 take a minute and a gigabyte).
MOST_RUNS, MOST_PATHS = 10**12, 1000


def counted(name: str, most: int | None = None, least: int = 1
            ) -> Callable[[click.Context, click.Parameter, int], int]:
    """An option callback: a count below *least* (or above *most*) is bad input,
    reported on one line (exit 2)."""

    def check(ctx: click.Context, param: click.Parameter, value: int) -> int:
        if value is not None and value < least:
            fail(f"{name} must be at least {least}, not {value}")
        if value is not None and most is not None and value > most:
            fail(f"{name} must be at most {most:,}, not {value:,}")
        return value

    return check


#: ``--strategy`` names: BS1 (the config's mission) or the synthesised strategy.
STRATEGIES = ("bs1", "optimal")


def _strategy_value(ctx: click.Context, param: click.Parameter, value: str) -> str:
    """An option callback: neither a name nor a file is bad input, on one line (exit 2)."""
    if value not in STRATEGIES and not Path(value).is_file():
        fail(f"--strategy must be bs1, optimal or a strategy file; "
             f"{'a folder' if Path(value).is_dir() else 'no file'} {value!r}")
    return value


#: ``--strategy bs1|optimal|FILE`` of ``explain``, ``simulate`` and ``distribution``.
strategy_option = click.option(
    "--strategy", "strategy", default="bs1", show_default=True, callback=_strategy_value,
    metavar="bs1|optimal|FILE",
    help="Analyse the mission under BS1 (the config's strategy), synthesize's strategy "
         "(optimal: safest, then fastest) or a strategy FILE of synthesize "
         "--export-strategy: the DTMC it induces on the mission MDP.")


def induced_mission(cfg: MissionConfig, strategy: str,
                    progress: ProgressCallback | None) -> InducedMission:
    """The mission under the strategy ``--strategy`` names (not ``bs1``)."""
    from veribattery.synthesis.induced_dtmc import file_mission, optimal_mission

    if strategy == "optimal":
        return optimal_mission(cfg, progress=progress)
    return file_mission(cfg, Path(strategy), progress=progress)


def _groupings(by: Sequence[str]) -> tuple[tuple[str, ...], ...]:
    """``--by cell,wind --by k+cell`` → ``(("cell",), ("wind",), ("k", "cell"))``."""
    return tuple(tuple(part.split("+")) for item in by for part in item.split(",") if part)


# ---------------------------------------------------------------------------
# explain
# ---------------------------------------------------------------------------


@click.command("explain", short_help="Where failures come from: breakdown and paths.")
@click.argument("config", type=PathParam(path_type=Path))
@set_option
@click.option("--top", default=3, show_default=True, callback=counted("--top", MOST_PATHS),
              help="How many most probable failure paths.")
@click.option("--by", "by", multiple=True, metavar="KEYS",
              help="Groupings, comma-separated; join keys with + for a joint grouping "
                   "(keys: k, cell, state, action, wind, level, recharges, or a variable).")
@click.option("-o", "--output", "--csv", "csv_file", type=PathParam(path_type=Path),
              help="Write the paths here as CSV, one row per step (--csv: the old name).")
@click.option("--force", is_flag=True, help="Overwrite an existing -o file.")
@click.option("--format", "output_format", type=click.Choice(["table", "json"]),
              default="table", show_default=True, help="Output format.")
@strategy_option
def explain_command(config: Path, overrides: tuple[str, ...], top: int, by: tuple[str, ...],
                    csv_file: Path | None, force: bool, output_format: str,
                    strategy: str) -> None:
    """Where the mission's failures come from: exact breakdown and most probable paths.

    The breakdown of P(failure) by cell, action, wind, voltage level and recharges is
    exact; actions named ``oob (...)`` are the steps where the battery runs out
    ("out of battery") or the recharge cap cuts the mission.
    """
    from veribattery.analyses.explain import explain_target
    from veribattery.analyses.mission_view import DEFAULT_GROUPINGS, MissionView, build_mission
    from veribattery.config import load_config

    with user_errors():
        check_output_file(csv_file, "-o", force=force, suffixes=CSV_SUFFIXES)
        cfg = load_config(config, overrides)
        with build_progress() as progress:
            view = (MissionView(build_mission(cfg, progress=progress)) if strategy == "bs1"
                    else _strategy_view(cfg, strategy, progress))
        explanation = explain_target(
            view.dtmc, view.dtmc.labels["failure"], name="failure",
            describe=view.columns, by=_groupings(by) or DEFAULT_GROUPINGS, top=top,
        )
        steps = [_mission_steps(view, path.states) for path in explanation.paths]
        if csv_file is not None:
            _write_paths_csv(csv_file, explanation, steps)
            print_written(csv_file)
    print_warnings(view.dtmc.warnings)
    if output_format == "json":
        click.echo(json.dumps(_explanation_json(explanation, steps)))
        return
    _print_explanation(explanation, steps, MISSION_COLUMNS, marker="recharge")
    print_dim(fit_text(OOB_NOTE))


def _strategy_view(cfg: MissionConfig, strategy: str,
                   progress: ProgressCallback | None) -> MissionView:
    """The mission under the strategy ``--strategy`` names, in the paper's terms."""
    from veribattery.analyses.mission_view import MissionModel
    from veribattery.analyses.strategy_view import StrategyView
    induced = induced_mission(cfg, strategy, progress)
    return StrategyView(MissionModel(cfg, induced.flat, induced.dtmc), induced.actions)


#: What the mission's ``oob`` actions mean, under the tables that show them.
OOB_NOTE = ("oob (X): out of battery: the drone could not pay for X (take-off, flight, "
            "inspection, landing) and the mission failed; oob (recharge cap): "
            "battery.max_recharges was reached with cells left.")


def _mission_steps(view: MissionView, states: IntArray) -> list[dict[str, object]]:
    rows = view.steps(states)
    for row in rows:
        row["charge"] = f"{row['charge_ah']:.1f} Ah"
        row["soc_text"] = f"{100 * float(str(row['soc'])):.0f}%"
    return rows


def _write_paths_csv(path: Path, explanation: Explanation,
                     steps: Sequence[Sequence[Mapping[str, object]]]) -> None:
    from veribattery.analyses.csvout import write_csv

    rows = []
    for number, (found, path_steps) in enumerate(zip(explanation.paths, steps, strict=True), 1):
        for row in path_steps:
            x, y = _xy(str(row.get("cell", "")))
            extra = {"path": number, "probability": repr(found.probability), "x": x, "y": y}
            rows.append([{**row, **extra}.get(c, "") for c in CSV_COLUMNS])
    write_csv(path, CSV_COLUMNS, rows)


def _xy(cell: str) -> tuple[object, object]:
    if not cell.startswith("["):
        return "", ""
    x, y = cell.strip("[]").split(",")
    return int(x), int(y)


def _explanation_json(explanation: Explanation,
                      steps: Sequence[Sequence[Mapping[str, object]]]) -> dict[str, object]:
    return {
        f"p_{explanation.target}": explanation.probability,
        "breakdown": {"+".join(g.keys): g.records() for g in explanation.groupings},
        "paths": [
            {"probability": p.probability, "log10_probability": p.log10_probability,
             "steps": p.steps,
             "states": [{k: v for k, v in row.items() if k not in ("charge", "soc_text")}
                        for row in rows]}
            for p, rows in zip(explanation.paths, steps, strict=True)
        ],
    }


def _print_explanation(
    explanation: Explanation, steps: Sequence[Sequence[Mapping[str, object]]],
    columns: Sequence[tuple[str, str]], *, marker: str | None,
) -> None:
    total = explanation.probability
    click.echo(fit_text(
        f"P({explanation.target}) = {format_value(total)}  (exact; the breakdown sums to it "
        f"over the {explanation.inflow.states.size:,} states {explanation.target} is "
        "entered from)"))
    for grouping in explanation.groupings:
        _print_grouping(grouping, total)
    for number, (path, rows) in enumerate(zip(explanation.paths, steps, strict=True), 1):
        click.echo()
        out.print(f"[bold]Path {number}[/]: probability {path.probability_text}, "
                  f"{path.steps} steps")
        _print_path(rows, columns, marker)
    if not explanation.paths:
        click.echo(f"\nNo path reaches {explanation.target}.")


def _print_grouping(grouping: Grouping, total: float) -> None:
    rows = []
    for values, p in grouping.groups[:GROUP_ROWS]:
        share = p / total if total > 0 else 0.0
        rows.append([*(str(v) for v in values), f"{p:.6g}", f"{100 * share:.2f}%",
                     "█" * round(BAR_WIDTH * share)])
    hidden = len(grouping.groups) - GROUP_ROWS
    if hidden > 0:
        rest = sum(p for _, p in grouping.groups[GROUP_ROWS:])
        rows.append([f"… {hidden} more", *[""] * (len(grouping.keys) - 1), f"{rest:.6g}", "",
                     ""])
    click.echo()
    print_table([*grouping.keys, "probability", "share", ""], rows, keys=len(grouping.keys),
                title=f"by {', '.join(grouping.keys)}")


def _print_path(rows: Sequence[Mapping[str, object]], columns: Sequence[tuple[str, str]],
                marker: str | None) -> None:
    """The path's steps, read down; a long run of recharge trips folded into one line."""
    from veribattery.analyses.folding import fold_path

    head, fold, end = fold_path([str(r["action"]) for r in rows], marker=marker)
    cells = [[str(rows[i][key]) for _, key in columns] for i in (*head, *end)]
    notes = {len(head): fold.describe(marker)} if fold is not None else {}
    print_table([h for h, _ in columns], cells, keys=2, notes=notes)


# ---------------------------------------------------------------------------
# simulate
# ---------------------------------------------------------------------------


def _simulation_options(function: Callable[..., None]) -> Callable[..., None]:
    for option in reversed((
        click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
                     help="Random seed (a non-negative integer)."),
        click.option("--max-steps", default=100_000, show_default=True,
                     callback=counted("--max-steps"),
                     help="Steps after which an undecided run stops (and is reported)."),
        click.option("-o", "--output", "--paths", "paths_file", type=PathParam(path_type=Path),
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
@_simulation_options
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
        check_output_file(paths_file, "-o", force=force, suffixes=CSV_SUFFIXES)
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


# ---------------------------------------------------------------------------
# prism MODEL --explain LABEL / --simulate N
# ---------------------------------------------------------------------------


def prism_analysis_options(function: Callable[..., None]) -> Callable[..., None]:
    """The ``--explain LABEL [--top N]`` and ``--simulate N`` options of ``prism``."""
    function = _simulation_options(function)
    for option in reversed((
        click.option("--explain", metavar="LABEL",
                     help="Break P(F LABEL) down by variable values; show the top paths."),
        click.option("--top", default=3, show_default=True, callback=counted("--top", MOST_PATHS),
                     help="With --explain: how many most probable paths."),
        click.option("--simulate", type=int, metavar="N",
                     callback=counted("--simulate", MOST_RUNS),
                     help="Also estimate the properties from N simulated runs."),
    )):
        function = option(function)
    return function


def prism_explain(model: Path, constants: Mapping[str, Value | str], label: str, top: int,
                  as_json: bool) -> None:
    """``prism MODEL --explain LABEL``: breakdown by variable values, and the top paths."""
    from veribattery.analyses.actions import action_labeller
    from veribattery.analyses.explain import explain_target, path_rows

    with user_errors():
        flat, dtmc = _build_prism(model, constants)
        if label not in dtmc.labels:
            known = ", ".join(f'"{name}"' for name in dtmc.labels)
            raise VeribatteryError(f'--explain "{label}": the model has no such label '
                                   f"(labels: {known})")
        explanation = explain_target(dtmc, dtmc.labels[label], name=label, top=top)
        labeller = action_labeller(flat)
        steps = [path_rows(dtmc, p, labeller) for p in explanation.paths]
    print_warnings(dtmc.warnings)
    if as_json:
        click.echo(json.dumps(_explanation_json(explanation, steps)))
        return
    columns = [("step", "step"), ("action", "action"), *((v, v) for v in dtmc.variable_names)]
    _print_explanation(explanation, steps, columns, marker=None)


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


def _build_prism(model: Path, constants: Mapping[str, Value | str]) -> tuple[FlatModel, DTMC]:
    from veribattery.explore import build_dtmc
    from veribattery.lang import flatten_model, parse_model

    flat = flatten_model(parse_model(model), constants)
    return flat, build_dtmc(flat)
