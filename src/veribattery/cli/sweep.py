"""``veribattery sweep``: the mission over a parameter grid."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click

from veribattery.cli.files import FIGURE_SUFFIXES, PathParam, check_output_file
from veribattery.cli.output import (
    err,
    exit_interrupted,
    format_value,
    json_value,
    print_dim,
    print_warnings,
    print_written,
    rich_console,
    set_option,
    user_errors,
)
from veribattery.cli.tables import print_table
from veribattery.errors import OptionError


def scheduler_address(ctx: click.Context, param: click.Parameter,
                      value: str | None) -> str | None:
    """An option callback: a ``--scheduler`` address that is malformed (a port that is no
    number, no port) is bad input, on one line (exit 2), before any cluster is reached."""
    if value is not None:
        from veribattery.sweep.execute import check_scheduler

        with user_errors():
            check_scheduler(value)
    return value


@click.command("sweep", short_help="Check a config at every point of a parameter grid.")
@click.argument("config", type=PathParam(path_type=Path))
@click.option(
    "--vary", "specs", multiple=True, metavar="KEY=SPEC",
    help="Sweep a config key over START:STOP:STEP (exact decimals, STOP included) or a,b,c "
    "(repeatable; the grid is the product, the first --vary varying slowest). Replaces the "
    "config's sweep.vary list.",
)
@set_option
@click.option(
    "--format", "output_format", type=click.Choice(["table", "csv", "json"]), default="table",
    show_default=True, help="Output format (csv and json are tidy: one row per point x property).",
)
@click.option("-o", "--output", "results", type=PathParam(path_type=Path), metavar="RESULTS",
              help="Durable results (.csv, .jsonl or .parquet): rows are written as points "
              "finish, and rerunning the same command resumes.")
@click.option("--force", is_flag=True,
              help="Start RESULTS afresh even if it holds another sweep's results, and "
              "overwrite an existing --plot file (a rerun that resumes RESULTS redraws the "
              "--plot it drew, while unchanged since, without --force).")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=None,
              help="Worker processes (default: the number of cores; 1: in this process).")
@click.option("--scheduler", metavar="tcp://HOST:PORT|local", callback=scheduler_address,
              help="Run the points on a Dask cluster ('local': a LocalCluster of -j workers).")
@click.option("--plot", "plot_path", type=PathParam(path_type=Path),
              help="Also write a figure (.png, .pdf, .svg, …).")
@click.option("--plot-property", "plot_property", metavar="NAME",
              help="Property to plot (default: the first).")
@click.option("--plot-x", "plot_x", metavar="KEY",
              help="Varied key on the x axis (default: the first numeric one; the others "
              "give one line per combination).")
def sweep_command(
    config: Path, specs: tuple[str, ...], overrides: tuple[str, ...], output_format: str,
    results: Path | None, force: bool, jobs: int | None, scheduler: str | None,
    plot_path: Path | None, plot_property: str | None, plot_x: str | None,
) -> None:
    """Check CONFIG at every point of a parameter grid.

    A point in synthesis mode (strategy.mode=synthesize, also as --vary
    strategy.mode=bs1,synthesize) gives the best return policy's certified Pmax of
    success: p_success_max and its interval's ends.

    Exit 1 if a point failed or a requirement fails anywhere (a summary line says which).
    """
    from veribattery.config import read_config
    from veribattery.sweep import any_requirement_fails, axes_from, default_jobs, summary_line
    from veribattery.sweep.grid import check_sets
    from veribattery.sweep.store import check_target
    from veribattery.sweep.synthesis_point import swept_properties

    with user_errors():
        document = read_config(config, overrides)
        cfg = document.validate()
        axes = axes_from(specs, cfg.sweep.vary, document)
        check_sets(axes, overrides, "--vary" if specs else "the config's sweep.vary")
        if results is not None:
            check_target(results, force=force)
        properties = swept_properties(cfg, axes)
        _check_plot_options(plot_path, plot_property, plot_x, axes, properties,
                            force or _drawn_by(results, plot_path))
        frame = run_with_progress(
            config, axes, overrides, results, jobs=jobs or default_jobs(), scheduler=scheduler,
            force=force,
        )
        if plot_path is not None and frame["property"].notna().any():
            _plot(frame, plot_path, plot_property, plot_x, properties, results)
    print_warnings(frame.attrs.get("warnings", ()))
    print_sweep(frame, [axis.key for axis in axes], output_format)
    err.print(summary_line(frame), markup=False)
    sys.exit(1 if frame.attrs.get("failed") or any_requirement_fails(frame) else 0)


def _drawn_by(results: Path | None, plot_path: Path | None) -> bool:
    """Whether the sweep resumed from *results* drew the existing *plot_path* itself, and
    it is unchanged since: a rerun of the same command then draws it again, where any
    other existing file needs --force (one changed since is refused, saying so)."""
    from veribattery.sweep.plot_record import check_redraw

    if results is None or plot_path is None or not plot_path.is_file():
        return False
    return check_redraw(results, plot_path)


def _plot(frame: Any, plot_path: Path, plot_property: str | None, plot_x: str | None,
          properties: Mapping[str, str], results: Path | None) -> None:
    """Draw the figure, and note it beside *results* as this sweep's own (see
    :func:`_drawn_by`)."""
    from veribattery.sweep import plot_sweep
    from veribattery.sweep.plot_record import record_plot

    name = plot_property or str(frame["property"].dropna().iloc[0])
    print_written(plot_sweep(frame, plot_x, name, plot_path, properties=properties))
    if results is not None:
        record_plot(results, plot_path)


def _check_plot_options(plot_path: Path | None, plot_property: str | None,
                        x_key: str | None, axes: Sequence[Any], properties: Mapping[str, str],
                        force: bool) -> None:
    """Every plot option checked before the first point: file, x key, property."""
    if plot_property is not None and plot_property not in properties:
        raise OptionError(f"--plot-property {plot_property}: the sweep has no such property "
                          f"(properties: {', '.join(properties)})")
    if plot_path is None:
        given = [option for option, value in (("--plot-property", plot_property),
                                              ("--plot-x", x_key)) if value is not None]
        if given:  # it would be ignored
            raise OptionError(f"{given[0]} chooses what --plot draws: give --plot FILE, or "
                              f"leave out {given[0]}")
        return
    from veribattery.sweep.plot import check_plot_target

    # The file first, as every command checks a figure (FIGURE_SUFFIXES, one wording);
    # the library's own check then has only the x key left to refuse.
    check_output_file(plot_path, "--plot", force=force, suffixes=FIGURE_SUFFIXES)
    check_plot_target(plot_path, x_key, [axis.key for axis in axes], property=plot_property,
                      properties=properties)


def run_with_progress(
    config: Path, axes: Sequence[Any], overrides: Sequence[str], results: Path | None,
    **options: Any,
) -> Any:
    """:func:`run_sweep` with progress on stderr; Ctrl-C says how to resume, exit 130."""
    from veribattery.sweep import run_sweep

    try:
        with sweep_progress() as (progress, on_point):
            return run_sweep(config, axes, overrides, progress, results=results,
                             on_point=on_point, notes=_note, **options)
    except KeyboardInterrupt:
        kept = (f"; finished points are kept in {results}: rerun to resume"
                if results is not None and results.exists() else "")
        exit_interrupted(f"interrupted{kept}")


def _note(text: str) -> None:
    err.print(text, markup=False, style="dim")


@contextmanager
def sweep_progress() -> Iterator[tuple[Callable[[int, int], None], Callable[[Any, Any], None]]]:
    """A rich progress bar (done, failed, ETA) on a terminal; else one line per point."""
    if not err.is_terminal:
        yield from _plain_lines()
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    failed = [0]
    columns = (TextColumn("checking grid points"), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.fields[failed]} failed"), TimeRemainingColumn())
    with Progress(*columns, console=rich_console(err), transient=True) as bar:
        task = bar.add_task("sweep", total=None, failed=0)

        def update(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total, failed=failed[0])

        def point(result: Any, _: Any) -> None:
            failed[0] += result.error is not None

        yield update, point


def _plain_lines() -> Iterator[tuple[Callable[[int, int], None], Callable[[Any, Any], None]]]:
    """For logs: ``[12/604] battery.capacity_ah=6.1: p_success=0.93, … (1.52 s)``."""
    from veribattery.sweep import describe_point

    counts = [0, 0]

    def update(done: int, total: int) -> None:
        counts[:] = [done, total]

    def point(result: Any, where: Any) -> None:
        outcome = (f"FAILED: {result.error}" if result.error is not None else
                   ", ".join(f"{v.name}={format_value(v.value)}" for v in result.values))
        click.echo(f"[{counts[0]}/{counts[1]}] {describe_point(where)}: {outcome} "
                   f"({result.seconds:.2f} s)", err=True)

    yield update, point


def print_sweep(frame: Any, keys: Sequence[str], output_format: str) -> None:
    """Table: one row per point, a column per property; csv/json: the tidy rows."""
    from veribattery.sweep import records, wide
    from veribattery.sweep.store import csv_text

    if output_format == "csv":  # as the -o RESULTS.csv file: true/false as in json
        click.echo(csv_text([str(c) for c in frame.columns], records(frame)), nl=False)
    elif output_format == "json":
        tidy = [{k: json_value(v) for k, v in row.items()} for row in records(frame)]
        click.echo(json.dumps({"axes": list(keys), "results": tidy}))
    else:
        points = wide(frame, keys)
        cells = [[NO_VALUE if v is None else format_value(v) for v in row.values()]
                 for row in records(points)]
        print_table([str(c) for c in points.columns], cells, keys=len(keys))
        if any(NO_VALUE in row for row in cells):
            print_dim(f"{NO_VALUE}: no value there (undefined, e.g. given P(success) = 0, "
                      "or not in that mode)")


#: A table cell without a value (NaN or absent in the tidy rows).
NO_VALUE = "—"
