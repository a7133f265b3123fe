"""``veribattery report``: the mission report, one self-contained HTML file."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import click
from click.core import ParameterSource

from veribattery.cli.analysis_options import MOST_PATHS, MOST_RUNS, counted
from veribattery.cli.files import PathParam, check_output_file
from veribattery.cli.output import (
    build_progress,
    print_warnings,
    print_written,
    set_option,
    user_errors,
)

#: The file types the report is written as.
HTML_SUFFIXES = (".html", ".htm")


def _note(text: str) -> None:
    click.echo(text, err=True)


@click.command("report", short_help="Write a mission report: one self-contained HTML file.")
@click.argument("config", type=PathParam(path_type=Path))
@click.option("-o", "--output", "output", type=PathParam(path_type=Path), required=True,
              help="The report to write (.html).")
@set_option
@click.option("--sweep", "sweep_file", type=PathParam(path_type=Path),
              help="A sweep's results of this config (RESULTS.csv, .jsonl or .parquet, with "
                   "its RESULTS.sweep.json) to draw, requirements' turning points marked.")
@click.option("--runs", default=1000, show_default=True, type=int,
              callback=counted("--runs", MOST_RUNS, least=0),
              help="Monte-Carlo runs beside the exact values (0: none).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0),
              help="The simulation's random seed (a non-negative integer).")
@click.option("--top", default=3, show_default=True, type=int,
              callback=counted("--top", MOST_PATHS),
              help="How many most probable failure paths.")
@click.option("--deadline", "deadlines", multiple=True, metavar="D",
              help="P(success within D): minutes (4800), hours (80h) or working days (10d); "
                   "repeatable (default: the whole working days the mission can end in).")
@click.option("--working-day", default="8h", show_default=True,
              help="Length of a working day 'd'.")
@click.option("--force", is_flag=True, help="Overwrite an existing -o file.")
def report_command(config: Path, output: Path, overrides: tuple[str, ...],
                   sweep_file: Path | None, runs: int, seed: int, top: int,
                   deadlines: tuple[str, ...], working_day: str, force: bool) -> None:
    """Write the mission report of CONFIG (YAML) to one HTML file that opens offline.

    The verdict first (each requirement on its certified interval), then the mission
    as a picture, where failures come from, mission time, Monte-Carlo estimates, a
    sweep's figures (--sweep) and what is needed to reproduce it. Exit 1 if a
    requirement fails (the report is written all the same).
    """
    from veribattery.analyses.distribution import parse_deadlines
    from veribattery.config import load_config
    from veribattery.report import ReportOptions, read_sweep, write_report

    with user_errors():
        check_output_file(output, "-o", force=force, suffixes=HTML_SUFFIXES)
        day, limits = parse_deadlines(working_day, deadlines)
        cfg = load_config(config, overrides)
        sweep = read_sweep(sweep_file, config, cfg) if sweep_file is not None else None
        options = ReportOptions(runs=runs, seed=seed, top=top, deadlines=limits,
                                working_day_minutes=day, title=config.name, settings=overrides,
                                command_line=_command_line(click.get_current_context()))
        with build_progress() as progress:
            data = write_report(output, cfg, options, sweep=sweep, progress=progress,
                                notes=_note if progress is None else progress.stage)
    print_warnings(data.verdict.warnings)
    print_written(output)
    for row in data.verdict.requirements:  # the page says so too; this is why the exit is 1
        if not row.holds:
            click.echo(f"{'FAIL' if row.decided else 'UNDECIDED'} {row.text}", err=True)
    sys.exit(0 if data.verdict.all_hold else 1)


def _command_line(ctx: click.Context) -> str:
    """The command with the arguments and options given (defaults left out), for the
    report's reproducibility section: ``veribattery report CONFIG -o FILE --set ...``."""
    words = ["veribattery", "report"]
    for param in ctx.command.params:
        name = param.name or ""
        if name == "force" or ctx.get_parameter_source(name) in (None, ParameterSource.DEFAULT):
            continue
        value = ctx.params[name]
        if isinstance(param, click.Argument):
            words.append(str(value))
            continue
        flag = max(param.opts, key=len)
        if isinstance(param, click.Option) and param.is_flag:
            words.extend([flag] if value else [])
            continue
        for item in value if param.multiple else (value,):
            words.extend([flag, str(item)])
    return shlex.join(words)
