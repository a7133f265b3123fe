"""The ``veribattery`` command line: parse options, call the library, print, set the exit code.

Exit status: 0 success (and every requirement holds), 1 a requirement fails,
2 bad input (any :class:`~veribattery.errors.VeribatteryError`, or a usage error).
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from veribattery.errors import VeribatteryError
from veribattery.lang import parse_constant_assignments
from veribattery.pipeline import ModelCheckRun, ProgressCallback, check_prism_file

if TYPE_CHECKING:
    from veribattery.analyses.table3 import Table3Comparison
    from veribattery.mission import MissionReport

F = TypeVar("F", bound=Callable[..., Any])

_out = Console(highlight=False, soft_wrap=True)
_err = Console(stderr=True, highlight=False, soft_wrap=True)


def fail(message: str) -> None:
    """Report a user error on one line and exit with status 2.

    Context lines after the first (a syntax error's source line and caret) are
    shown on a terminal only, so logs and pipes get exactly one line.
    """
    first, _, context = message.partition("\n")
    _err.print(f"[bold red]error:[/] {escape(first)}", markup=True, highlight=False)
    if context and _err.is_terminal:
        _err.print(context, markup=False, highlight=False)
    sys.exit(2)


@contextmanager
def user_errors() -> Iterator[None]:
    """Turn library errors into one-line messages and exit status 2 (never a traceback)."""
    try:
        yield
    except VeribatteryError as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"{exc.filename or ''}: {exc.strerror or exc}")


@contextmanager
def build_progress() -> Iterator[ProgressCallback | None]:
    """A live state counter on stderr while the state space is explored (TTY only)."""
    if not _err.is_terminal:
        yield None
        return
    with _err.status("exploring states…") as status:

        def update(states: int, frontier: int) -> None:
            status.update(f"exploring states… {states:,} found, frontier {frontier:,}")

        yield update


def json_value(value: object) -> object:
    """A result value as strict JSON: infinities become the string ``"Infinity"``."""
    if isinstance(value, float) and math.isinf(value):
        return "Infinity" if value > 0 else "-Infinity"
    return value


def format_value(value: object) -> str:
    """A result value for a table: booleans as true/false, numbers to 12 significant digits."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "Infinity" if math.isinf(value) else f"{value:.12g}"
    return str(value)


def print_warnings(warnings: Sequence[str]) -> None:
    """Print the model's warnings (deadlocks, nondeterminism) to stderr."""
    for warning in warnings:
        _err.print(f"[yellow]warning:[/] {escape(warning)}", markup=True)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="veribattery")
def cli() -> None:
    """Verify battery-powered robot missions with probabilistic model checking."""


@cli.command("prism")
@click.argument("model", type=click.Path(path_type=Path))
@click.option("--props", "props", type=click.Path(path_type=Path), help="Properties file.")
@click.option(
    "--property",
    "selectors",
    multiple=True,
    metavar="TEXT|INDEX|NAME",
    help="Property text, or a 1-based index or name in --props (repeatable).",
)
@click.option("--const", "consts", multiple=True, metavar="NAME=VALUE", help="Undefined constant.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def prism_command(
    model: Path,
    props: Path | None,
    selectors: tuple[str, ...],
    consts: tuple[str, ...],
    as_json: bool,
) -> None:
    """Check PCTL properties of a PRISM DTMC MODEL file."""
    with user_errors(), build_progress() as progress:
        constants = parse_constant_assignments(consts)
        run = check_prism_file(
            model, props_source=props, selectors=selectors, constants=constants, progress=progress
        )
    print_warnings(run.warnings)
    if as_json:
        click.echo(json.dumps(prism_json(run)))
    else:
        print_prism_run(run)


def prism_json(run: ModelCheckRun) -> dict[str, object]:
    """The ``prism --json`` document."""
    return {
        "model": run.model_summary,
        "results": [
            {"property": r.property.text, "value": json_value(r.value)} for r in run.results
        ],
        "timings_s": {k: round(v, 6) for k, v in run.timings_s.items()},
    }


def print_prism_run(run: ModelCheckRun) -> None:
    """Model size, then one table row per property."""
    size = run.model_summary
    _out.print(
        f"Model: {size['states']:,} states, {size['transitions']:,} transitions, "
        f"{size['initial_states']} initial, {size['deadlocks']} deadlocks"
    )
    table = Table("property", "value", title=None, show_edge=False)
    for result in run.results:
        table.add_row(result.property.text, format_value(result.value))
    _out.print(table)
    timings = ", ".join(f"{k} {v:.3f}s" for k, v in run.timings_s.items())
    _out.print(f"Time: {timings}", style="dim")


def main(argv: Sequence[str] | None = None) -> None:
    """Console-script entry point."""
    cli.main(args=list(argv) if argv is not None else None, prog_name="veribattery")


# ---------------------------------------------------------------------------
# Mission commands


def _set_option(function: F) -> F:
    return click.option(
        "--set", "overrides", multiple=True, metavar="KEY=VALUE",
        help="Override a config key (VALUE is YAML), e.g. --set farm.base=[1,1].",
    )(function)


@cli.command("check")
@click.argument("config", type=click.Path(path_type=Path))
@_set_option
@click.option(
    "--format", "output_format", type=click.Choice(["table", "json", "csv"]), default="table",
    show_default=True, help="Output format.",
)
@click.option(
    "--emit", "emit_dir", type=click.Path(path_type=Path), help="Also write the model files here."
)
@click.option("--force", is_flag=True, help="Let --emit overwrite existing files.")
def check_command(
    config: Path, overrides: tuple[str, ...], output_format: str, emit_dir: Path | None, force: bool
) -> None:
    """Verify the mission of CONFIG (YAML); exit 1 if a requirement fails."""
    from veribattery.config import load_config
    from veribattery.mission import check_mission, mission_files, write_files

    with user_errors():
        cfg = load_config(config, overrides)
        with build_progress() as progress:
            report = check_mission(cfg, progress=progress)
        if emit_dir is not None:
            write_files(mission_files(cfg), emit_dir, force=force)
    print_warnings(report.warnings)
    {"table": print_mission_table, "json": print_mission_json, "csv": print_mission_csv}[
        output_format
    ](report)
    sys.exit(0 if report.all_requirements_hold else 1)


def print_mission_table(report: MissionReport) -> None:
    """Model size, named results, requirements, timings."""
    dtmc = report.run.dtmc
    _out.print(f"Model: {dtmc.num_states:,} states, {dtmc.num_transitions:,} transitions")
    table = Table("property", "formula", "value", show_edge=False)
    for result in report.run.results:
        table.add_row(result.property.name or "", result.property.text, format_value(result.value))
    _out.print(table)
    for outcome in report.requirements:
        verdict = "[green]PASS[/]" if outcome.holds else "[bold red]FAIL[/]"
        _out.print(f"{verdict} {outcome.requirement} (value {format_value(outcome.value)})")
    timings = ", ".join(f"{k} {v:.3f}s" for k, v in report.run.timings_s.items())
    _out.print(f"Time: {timings}", style="dim")


def mission_json(report: MissionReport) -> dict[str, object]:
    """The ``check --format json`` document."""
    dtmc = report.run.dtmc
    return {
        "model": {"states": dtmc.num_states, "transitions": dtmc.num_transitions},
        "results": {name: json_value(value) for name, value in report.values.items()},
        "requirements": [
            {**o.as_dict(), "value": json_value(o.value)} for o in report.requirements
        ],
        "timings_s": {k: round(v, 6) for k, v in report.run.timings_s.items()},
    }


def print_mission_json(report: MissionReport) -> None:
    """One JSON object on stdout."""
    click.echo(json.dumps(mission_json(report)))


def print_mission_csv(report: MissionReport) -> None:
    """``property,value`` rows (values with full precision)."""
    click.echo("property,value")
    for name, value in report.values.items():
        click.echo(f"{name},{format_value(value) if isinstance(value, bool) else repr(value)}")


@cli.command("emit")
@click.argument("config", type=click.Path(path_type=Path))
@click.option("-o", "--output", "out_dir", type=click.Path(path_type=Path), required=True,
              help="Directory for model.prism, properties.props, config.resolved.yaml.")
@_set_option
@click.option("--force", is_flag=True, help="Overwrite existing files.")
def emit_command(config: Path, out_dir: Path, overrides: tuple[str, ...], force: bool) -> None:
    """Write the PRISM model and properties of CONFIG for PRISM or Storm."""
    from veribattery.config import load_config
    from veribattery.lang import flatten_model, parse_model, parse_properties
    from veribattery.mission import MODEL_FILE, PROPERTIES_FILE, mission_files, write_files

    with user_errors():
        files = mission_files(load_config(config, overrides))
        # The emitted text must be valid for our own front end before it is written.
        flatten_model(parse_model(files.model, name=MODEL_FILE))
        parse_properties(files.properties, name=PROPERTIES_FILE)
        written = write_files(files, out_dir, force=force)
    for path in written:
        click.echo(str(path))


@cli.command("reproduce")
@click.argument("what", type=click.Choice(["table3"]))
@click.option("--format", "output_format", type=click.Choice(["table", "json"]), default="table",
              show_default=True)
def reproduce_command(what: str, output_format: str) -> None:
    """Re-run the seed paper's Table 3 and print it beside the paper's figures."""
    from veribattery.analyses.table3 import reproduce_table3

    with user_errors():
        rows = reproduce_table3(progress=_err.print if _err.is_terminal else None)
    if output_format == "json":
        click.echo(json.dumps([row.as_dict() for row in rows]))
        return
    print_table3(rows)


def print_table3(rows: Sequence[Table3Comparison]) -> None:
    """Paper vs veribattery, with relative differences."""
    from veribattery.analyses.paper import SOURCE

    table = Table("case", "quantity", "paper", "veribattery", "rel. diff", show_edge=False,
                  title=f"Table 3 — {SOURCE} vs veribattery")
    for row in rows:
        for quantity, paper, ours, diff in row.lines():
            table.add_row(row.paper.case, quantity, paper, ours, diff)
        table.add_section()
    _out.print(table)
    _out.print(
        "State and transition counts are not expected to match: the paper's model uses a "
        "different encoding (see docs/model-spec.md).", style="dim",
    )


@cli.command("sweep")
@click.argument("config", type=click.Path(path_type=Path))
@click.option(
    "--vary", "specs", multiple=True, required=True, metavar="KEY=SPEC",
    help="Sweep a config key over START:STOP:STEP (exact decimals, STOP included) or a,b,c "
    "(repeatable; the grid is the product, the first --vary varying slowest).",
)
@_set_option
@click.option(
    "--format", "output_format", type=click.Choice(["table", "csv", "json"]), default="table",
    show_default=True, help="Output format (csv and json are tidy: one row per point x property).",
)
@click.option("-o", "--output", "csv_path", type=click.Path(path_type=Path),
              help="Also write the tidy results to this CSV file.")
@click.option("--plot", "plot_path", type=click.Path(path_type=Path),
              help="Also write a figure (.png, .pdf, .svg, …).")
@click.option("--plot-property", "plot_property", metavar="NAME",
              help="Property to plot (default: the first).")
@click.option("--plot-x", "plot_x", metavar="KEY",
              help="Varied key on the x axis (default: the first).")
def sweep_command(
    config: Path, specs: tuple[str, ...], overrides: tuple[str, ...], output_format: str,
    csv_path: Path | None, plot_path: Path | None, plot_property: str | None, plot_x: str | None,
) -> None:
    """Check CONFIG at every point of a parameter grid; exit 1 if a requirement fails anywhere."""
    from veribattery.sweep import any_requirement_fails, parse_axis, plot_sweep, run_sweep

    with user_errors():
        axes = [parse_axis(spec) for spec in specs]
        x_key = plot_x or axes[0].key
        if plot_path is not None:
            from veribattery.sweep.plot import check_plot_target

            check_plot_target(plot_path, x_key, [axis.key for axis in axes])
        with sweep_progress() as progress:
            frame = run_sweep(config, axes, overrides, progress=progress)
        # Everything is computed before anything is written: no partial output on error.
        if plot_path is not None:
            plot_sweep(frame, x_key, plot_property or str(frame["property"].iloc[0]), plot_path)
        if csv_path is not None:
            frame.to_csv(csv_path, index=False)
    print_warnings(frame.attrs.get("warnings", ()))
    print_sweep(frame, [axis.key for axis in axes], output_format)
    sys.exit(1 if any_requirement_fails(frame) else 0)


@contextmanager
def sweep_progress() -> Iterator[Callable[[int, int], None] | None]:
    """A progress bar of grid points on stderr (TTY only)."""
    if not _err.is_terminal:
        yield None
        return
    from rich.progress import Progress

    with Progress(console=_err, transient=True) as bar:
        task = bar.add_task("checking grid points", total=None)

        def update(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total,
                       description=f"checking grid points ({done} of {total})")

        yield update


def print_sweep(frame: Any, keys: Sequence[str], output_format: str) -> None:
    """Table: one row per point, a column per property; csv/json: the tidy rows."""
    from veribattery.sweep import records, wide

    if output_format == "csv":
        click.echo(frame.to_csv(index=False), nl=False)
    elif output_format == "json":
        rows = [{k: json_value(v) for k, v in row.items()} for row in records(frame)]
        click.echo(json.dumps({"axes": list(keys), "results": rows}))
    else:
        points = wide(frame, keys)
        table = Table(*map(str, points.columns), show_edge=False)
        for row in records(points):
            table.add_row(*(format_value(v) for v in row.values()))
        # Wider than the terminal rather than folding numbers: a sweep table is for reading.
        natural = _out.measure(table, options=_out.options.update_width(10_000)).maximum
        (_out if natural <= _out.width else Console(highlight=False, width=natural)).print(table)
