"""``veribattery prism``: check properties of any PRISM DTMC file."""

from __future__ import annotations

import json
from pathlib import Path

import click
from rich.table import Table

from veribattery.checker import CheckResult
from veribattery.cli.output import (
    build_progress,
    format_value,
    json_value,
    out,
    print_warnings,
    user_errors,
)
from veribattery.lang import parse_constant_assignments
from veribattery.pipeline import ModelCheckRun, check_prism_file


@click.command("prism")
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
        "results": [_json_result(r) for r in run.results],
        "timings_s": {k: round(v, 6) for k, v in run.timings_s.items()},
    }


def _json_result(result: CheckResult) -> dict[str, object]:
    """One result: its value, plus the range over several initial states and the
    states a print/argmin/argmax filter listed, when there are any."""
    entry: dict[str, object] = {"property": result.property.text,
                                "value": json_value(result.value)}
    if result.value_range is not None:
        entry["range"] = [json_value(v) for v in result.value_range]
    if result.printed:
        entry["states"] = list(result.printed)
    return entry


def _shown(result: CheckResult) -> str:
    """The value as PRISM reports it: ``[low, high]`` for a range."""
    if result.value_range is not None:
        low, high = result.value_range
        return f"[{format_value(low)}, {format_value(high)}]"
    return format_value(result.value)


def print_prism_run(run: ModelCheckRun) -> None:
    """Model size, then one table row per property."""
    size = run.model_summary
    out.print(
        f"Model: {size['states']:,} states, {size['transitions']:,} transitions, "
        f"{size['initial_states']} initial, {size['deadlocks']} deadlocks"
    )
    table = Table("property", "value", title=None, show_edge=False)
    for result in run.results:
        table.add_row(result.property.text, _shown(result))
    out.print(table)
    for result in run.results:
        if result.printed:
            out.print(f"States of {result.property.text}:", highlight=False)
            for line in result.printed:
                out.print(f"  {line}", highlight=False, markup=False)
    timings = ", ".join(f"{k} {v:.3f}s" for k, v in run.timings_s.items())
    out.print(f"Time: {timings}", style="dim")

