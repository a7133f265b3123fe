"""``veribattery reproduce``: the seed paper's results beside ours."""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from veribattery.cli.files import PathParam, check_output_dir
from veribattery.cli.output import err, exit_interrupted, fail, print_written, user_errors
from veribattery.cli.sweep import scheduler_address
from veribattery.cli.tables import fit_text, print_table

if TYPE_CHECKING:
    from veribattery.analyses.table3 import Table3Comparison

#: Off a terminal, a progress line at least this often (seconds) while points finish.
PROGRESS_EVERY_S = 60.0


@click.command("reproduce", short_help="Re-run the paper's Table 3, Fig. 6 and Fig. 8.")
@click.argument("what", type=click.Choice(["table3", "fig6", "fig8", "all"]))
@click.option("--format", "output_format", type=click.Choice(["table", "json"]), default="table",
              show_default=True, help="How Table 3 is printed.")
@click.option("-o", "--output", "out_dir", type=PathParam(path_type=Path, file_okay=False),
              help="Folder for the figures (PNG, SVG), their CSVs and the resumable sweep "
              "results (default for fig6/fig8: the current folder; required for all).")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=None,
              help="Worker processes for the sweeps (default: the number of cores).")
@click.option("--scheduler", metavar="tcp://HOST:PORT|local", callback=scheduler_address,
              help="Run the sweeps on a Dask cluster.")
@click.option("--force", is_flag=True,
              help="Overwrite the tables and figures of an earlier run in DIR.")
@click.option("--optimal", is_flag=True,
              help="Fig. 6 also draws the best policy's Pmax of success beside each curve "
              "of the BS1 strategy (one MDP per model and capacity).")
def reproduce_command(
    what: str, output_format: str, out_dir: Path | None, jobs: int | None,
    scheduler: str | None, force: bool, optimal: bool,
) -> None:
    """Re-run the seed paper's Table 3, Fig. 6 and Fig. 8 (all: every one, into -o DIR).

    \b
    The figures come from one sweep (four battery models x 5.0-20.0 Ah, 604
    points) that checks only the properties drawn. Its rows are kept in
    DIR/capacity_sweep.csv (fig6 or fig8 alone: DIR/fig6_sweep.csv or
    DIR/fig8_sweep.csv), so an interrupted run resumes where it stopped.
    The files written are listed on stderr; stdout has only Table 3.
    --optimal adds to Fig. 6 and its CSV, per model and capacity, the certified
    Pmax of success over every return policy (veribattery synthesize's), from a
    second sweep in synthesis mode, resumable in DIR/fig6_optimal_sweep.csv.
    """
    if optimal and what not in ("fig6", "all"):
        raise click.UsageError("--optimal draws on Fig. 6: use it with fig6 or all")
    if what == "table3" and out_dir is None:
        _table3_in_process(output_format)
        return
    if what == "all" and out_dir is None:
        raise click.UsageError("reproduce all needs -o DIR")
    from veribattery.sweep import default_jobs

    directory = out_dir or Path(".")
    with user_errors():
        check_output_dir(directory, "-o", force=force, names=_products(what))
    options = _options(jobs or default_jobs(), scheduler)
    new = [folder for folder in (directory, *directory.parents) if not folder.exists()]
    try:
        _reproduce(what, directory, options, output_format, optimal)
    except SystemExit as exc:
        if exc.code:  # bad input (an unreachable scheduler): leave no empty folder behind
            _remove_empty(new)
        raise
    except KeyboardInterrupt:
        exit_interrupted(_kept(directory, what, optimal))


def _kept(directory: Path, what: str, optimal: bool) -> str:
    """``interrupted``, naming the results files that keep the finished points."""
    from veribattery.analyses.figures import sweep_results

    kept = [str(directory / name) for name in sweep_results(what, optimal)
            if (directory / name).exists()]
    return (f"interrupted; finished points are kept in {', '.join(kept)}: rerun to resume"
            if kept else "interrupted")


def _reproduce(what: str, directory: Path, options: Any, output_format: str,
               optimal: bool) -> None:
    from veribattery.analyses import figures

    with user_errors():
        if what in ("table3", "all"):
            table = figures.table3_frame(figures.table3_sweep(_mkdir(directory), options))
            _write_csv(table, directory / "table3.csv")
            _print_table3_frame(table, output_format)
        if what != "table3":
            drawn = figures.FIGURES if what == "all" else (what,)
            frame = figures.capacity_sweep(_mkdir(directory), options, drawn)
            _report_failures(frame, figures.capacity_results(drawn))
            if what in ("fig6", "all"):
                best = _optimal_frame(directory, options) if optimal else None
                print_written(*figures.draw_fig6(frame, directory, best))
            if what in ("fig8", "all"):
                print_written(*figures.draw_fig8(frame, directory))


def _optimal_frame(directory: Path, options: Any) -> Any:
    """Per model and capacity of Fig. 6, the best policy's certified Pmax of success."""
    from veribattery.analyses import figures

    err.print("Pmax of success: the mission MDP at each model and capacity", markup=False,
              style="dim")
    frame = figures.optimal_sweep(directory, options)
    _report_failures(frame, figures.OPTIMAL_RESULTS)
    return figures.optimal_curves(frame)


def _table3_in_process(output_format: str) -> None:
    from veribattery.analyses.table3 import reproduce_table3

    with user_errors():
        rows = reproduce_table3(progress=err.print if err.is_terminal else None)
    if output_format == "json":
        click.echo(json.dumps([row.as_dict() for row in rows]))
        return
    print_table3(rows)


def _options(jobs: int, scheduler: str | None) -> Any:
    from veribattery.analyses.figures import SweepOptions

    def note(text: str) -> None:
        err.print(text, markup=False, style="dim")

    told = [time.monotonic()]

    def progress(done: int, total: int) -> None:
        # every 25 points, or a minute after the last line (a Pmax point takes 5-20 s)
        now = time.monotonic()
        if done and (done == total or done % 25 == 0 or now - told[0] >= PROGRESS_EVERY_S):
            err.print(f"{done} of {total} points", markup=False, style="dim")
            told[0] = now

    return SweepOptions(jobs, scheduler, progress, note)


def _remove_empty(folders: list[Path]) -> None:
    """Remove *folders* (deepest first) that this run made and left empty."""
    for folder in folders:
        if folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()


def _mkdir(directory: Path) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    return directory


def _products(what: str) -> list[str]:
    """The tables and figures *what* writes (the sweeps' results are resumed, not these)."""
    from veribattery.analyses.figures import FIGURE_FILES, FIGURES

    names = ["table3.csv"] if what in ("table3", "all") else []
    drawn = FIGURES if what == "all" else (what,) if what != "table3" else ()
    return names + [f"{figure}{suffix}" for figure in drawn for suffix in FIGURE_FILES]


def _write_csv(table: Any, path: Path) -> None:
    from veribattery._files import staged

    with staged(path) as temporary:
        table.to_csv(temporary, index=False)  # shortest round-trip repr: 0.3, not 0.2999…
    print_written(path)


def _report_failures(frame: Any, results: str) -> None:
    from veribattery.cli.output import print_warnings
    from veribattery.sweep import summary_line

    print_warnings(frame.attrs.get("warnings", ()))
    if frame.attrs.get("failed"):
        fail(f"{summary_line(frame)}; see the error column of {results}")


def _print_table3_frame(table: Any, output_format: str) -> None:
    if output_format == "json":
        click.echo(table.to_json(orient="records"))
        return
    rows = []
    for row in table.to_dict("records"):
        for q in ("p_success", "exp_mission_time", "exp_recharges"):
            rows.append((row["case"], q, f"{row[q + '_paper']:g}", f"{row[q + '_ours']:.6g}",
                         f"{row[q + '_rel_diff']:+.2%}"))
    print_table(TABLE3_COLUMNS, rows, keys=2, title="Table 3 — paper vs veribattery")


#: Columns of the Table 3 comparison.
TABLE3_COLUMNS = ("case", "quantity", "paper", "veribattery", "rel. diff")


def print_table3(rows: Sequence[Table3Comparison]) -> None:
    """Paper vs veribattery, with relative differences."""
    from veribattery.analyses.paper import SOURCE

    lines = [(row.paper.case, quantity, paper, ours, diff)
             for row in rows for quantity, paper, ours, diff in row.lines()]
    print_table(TABLE3_COLUMNS, lines, keys=2, title=f"Table 3 — {SOURCE} vs veribattery")
    err.print(fit_text("State and transition counts are not expected to match: the paper's "
                       "model uses a different encoding (see docs/model-spec.md)."),
              style="dim", markup=False)
