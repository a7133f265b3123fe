"""``veribattery sweep``: the mission over a parameter grid."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click
from rich.console import Console
from rich.table import Table

from veribattery.cli.output import (
    err,
    format_value,
    json_value,
    out,
    print_warnings,
    set_option,
    user_errors,
)


@click.command("sweep")
@click.argument("config", type=click.Path(path_type=Path))
@click.option(
    "--vary", "specs", multiple=True, required=True, metavar="KEY=SPEC",
    help="Sweep a config key over START:STOP:STEP (exact decimals, STOP included) or a,b,c "
    "(repeatable; the grid is the product, the first --vary varying slowest).",
)
@set_option
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
    if not err.is_terminal:
        yield None
        return
    from rich.progress import Progress

    with Progress(console=err, transient=True) as bar:
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
        natural = out.measure(table, options=out.options.update_width(10_000)).maximum
        (out if natural <= out.width else Console(highlight=False, width=natural)).print(table)

