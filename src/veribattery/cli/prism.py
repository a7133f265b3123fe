"""``veribattery prism``: check properties of any PRISM DTMC file."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from veribattery.cli.explain import prism_analysis_options, prism_explain, prism_simulate
from veribattery.cli.output import (
    EXACT_NOTE,
    build_progress,
    exact_text,
    format_result,
    format_value,
    is_long_exact,
    json_value,
    out,
    print_imprecise,
    print_timings,
    print_warnings,
    result_bounds,
    user_errors,
)
from veribattery.cli.tables import fit_text, print_table

if TYPE_CHECKING:
    from veribattery.checker import CheckResult
    from veribattery.pipeline import ModelCheckRun


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
@click.option(
    "--exact", is_flag=True,
    help="Compute in exact rational arithmetic; results as p/q (JSON: \"exact\").",
)
@prism_analysis_options
def prism_command(
    model: Path,
    props: Path | None,
    selectors: tuple[str, ...],
    consts: tuple[str, ...],
    as_json: bool,
    exact: bool,
    **analysis: Any,
) -> None:
    """Check PCTL properties of a PRISM DTMC MODEL file."""
    from veribattery.lang import parse_constant_assignments
    from veribattery.pipeline import check_prism_file

    if analysis["explain"] is not None:
        with user_errors():
            constants = parse_constant_assignments(consts)
        prism_explain(model, constants, analysis["explain"], analysis["top"], as_json)
        return
    with user_errors(), build_progress() as progress:
        constants = parse_constant_assignments(consts)
        run = check_prism_file(
            model, props_source=props, selectors=selectors, constants=constants, progress=progress,
            exact=exact, keep_states=False,
        )
    print_warnings(run.warnings)
    print_imprecise(run.results)
    if analysis["simulate"] is not None:
        prism_simulate(run, model, constants, analysis["simulate"], seed=analysis["seed"],
                       max_steps=analysis["max_steps"], paths_file=analysis["paths_file"],
                       path_count=analysis["path_count"], as_json=as_json)
        return
    if as_json:
        click.echo(json.dumps(prism_json(run)))
    else:
        print_prism_run(run)


def prism_json(run: ModelCheckRun) -> dict[str, object]:
    """The ``prism --json`` document."""
    return {
        "model": run.model_summary,
        "results": [_result_json(r) for r in run.results],
        "timings_s": {k: round(v, 6) for k, v in run.timings_s.items()},
    }


def _result_json(result: CheckResult) -> dict[str, object]:
    """One result: property (and its name, if it has one), value, ``exact`` under
    ``--exact``, for numbers the certified bounds and whether they meet the
    precision, plus the range over several initial states and the states a
    print/argmin/argmax filter listed."""
    entry: dict[str, object] = {"property": result.property.text}
    if result.property.name is not None:
        entry["name"] = result.property.name
    entry["value"] = json_value(result.value)
    exact = exact_text(result)
    if exact is not None:
        entry["exact"] = exact
    bounds = result_bounds(result)
    if bounds is not None:
        entry["bounds"] = bounds
        entry["precise"] = result.precise
    if result.value_range is not None:
        entry["range"] = [json_value(v) for v in result.value_range]
    if result.printed:
        entry["states"] = list(result.printed)
    return entry


def _shown(result: CheckResult) -> str:
    """The value as PRISM reports it: ``[low, high]`` for a range, else
    :func:`format_result` (``value ± error`` or ``p/q ≈ value``)."""
    if result.value_range is not None:
        low, high = result.value_range
        return f"[{format_value(low)}, {format_value(high)}]"
    return format_result(result)


def _labelled(result: CheckResult) -> str:
    """The property as written in a properties file: ``"name": formula``."""
    name = result.property.name
    return result.property.text if name is None else f'"{name}": {result.property.text}'


def print_prism_run(run: ModelCheckRun) -> None:
    """Model size, then one table row per property."""
    size = run.model_summary
    click.echo(
        f"Model: {size['states']:,} states, {size['transitions']:,} transitions, "
        f"{size['initial_states']} initial, {size['deadlocks']} deadlocks"
    )
    rows = [(_labelled(result), _shown(result)) for result in run.results]
    print_table(("property", "value"), rows)
    if any(is_long_exact(value) for _, value in rows):
        out.print(fit_text(EXACT_NOTE), style="dim", markup=False)
    for result in run.results:
        if result.printed:
            click.echo(f"States of {result.property.text}:")
            for line in result.printed:
                click.echo(f"  {line}")
    print_timings(run.timings_s)
