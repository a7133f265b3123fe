"""``veribattery prism``: check properties of any PRISM DTMC file."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from veribattery._text import count_of
from veribattery.cli.analysis_options import MOST_PATHS, MOST_RUNS, counted
from veribattery.cli.experiments import check_experiment_options, print_experiment
from veribattery.cli.explain import prism_explain
from veribattery.cli.files import CSV_SUFFIXES, PathParam, check_output_file
from veribattery.cli.output import (
    build_progress,
    check_modes,
    exact_notes,
    exact_text,
    fail,
    format_result,
    format_value,
    print_dim,
    print_imprecise,
    print_timings,
    print_warnings,
    property_value,
    result_bounds,
    user_errors,
)
from veribattery.cli.progress import limited
from veribattery.cli.simulate import prism_simulate, simulation_options
from veribattery.cli.strategy import (
    check_strategy_options,
    export_run_strategy,
    hopeless_export_check,
    strategy_options,
)
from veribattery.cli.tables import fit_text, print_table
from veribattery.errors import OptionError

if TYPE_CHECKING:
    from veribattery.checker import CheckResult
    from veribattery.pipeline import ModelCheckRun
    from veribattery.pipeline.mdp import MdpCheckRun


def _analysis_options(function: Callable[..., None]) -> Callable[..., None]:
    """The ``--explain LABEL [--top N]`` and ``--simulate N`` options of ``prism``."""
    function = simulation_options(function)
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


@click.command("prism", short_help="Check properties of any PRISM DTMC or MDP file.")
@click.argument("model", type=PathParam(path_type=Path))
@click.option("--props", "props", type=PathParam(path_type=Path), help="Properties file.")
@click.option(
    "--property",
    "selectors",
    multiple=True,
    metavar="TEXT|INDEX|NAME",
    help="Property text, or a 1-based index or name in --props (repeatable).",
)
@click.option("--const", "consts", multiple=True, metavar="NAME=VALUE",
              help="Undefined constant; NAME=a:b or a:step:b checks every value (PRISM's "
                   "experiments).")
@click.option(
    "--format", "output_format", type=click.Choice(["table", "json", "csv"]), default=None,
    help="Output format [default: table].",
)
@click.option("--json", "as_json", is_flag=True, help="The same as --format json.")
@click.option(
    "--exact", is_flag=True,
    help="Compute in exact rational arithmetic; results as p/q (JSON: \"exact\").",
)
@click.option(
    "--max-states", type=click.IntRange(min=1), default=None, metavar="N",
    help="Stop the build (exit 2) once more than N states are found.",
)
@click.option(
    "--all-states", is_flag=True,
    help="Build every reachable state, as PRISM does. By default, as Storm does, states "
         "where every property's value is already known (the targets of F and U, ...) are "
         "not expanded.",
)
@_analysis_options
@strategy_options
def prism_command(
    model: Path,
    props: Path | None,
    selectors: tuple[str, ...],
    consts: tuple[str, ...],
    output_format: str | None,
    as_json: bool,
    exact: bool,
    max_states: int | None,
    all_states: bool,
    **analysis: Any,
) -> None:
    """Check PCTL properties of a PRISM DTMC or MDP MODEL file."""
    from veribattery.lang import parse_constant_assignments
    from veribattery.pipeline import ModelCheckRun as ModelCheckRunType
    from veribattery.pipeline import check_prism_file

    with user_errors():
        output_format = _format(output_format, as_json)
        check_output_file(analysis["paths_file"], "-o", force=analysis["force"],
                          suffixes=CSV_SUFFIXES)
        check_strategy_options(analysis)
        if exact and (analysis["strategy_file"] is not None
                      or analysis["induced_dir"] is not None):
            raise OptionError("--export-strategy and --export-induced are not available with "
                              "--exact: leave out --exact to export the strategy (its "
                              "optimality is certified)")
        if analysis["paths_file"] is not None and analysis["simulate"] is None:
            raise OptionError("-o writes the sampled paths of --simulate N: give --simulate, "
                              "or leave out -o")
        _check_modes(analysis)
        _check_explain(analysis["explain"], {"--props": props is not None,
                                             "--property": bool(selectors), "--exact": exact,
                                             "--max-states": max_states is not None})
        if analysis["explain"] is not None and output_format == "csv":
            raise OptionError("--format csv: --explain prints a table or json; "
                              "use --format table or --format json")
    as_json = output_format == "json"
    with user_errors():
        constants = parse_constant_assignments(consts)
        if any(":" in value for value in constants.values()):  # a range: an experiment
            from veribattery.lang.experiments import constant_points  # (fractions, decimal)

            check_experiment_options(analysis)
            _experiment(model, props, selectors, constant_points(constants), output_format,
                        exact, (max_states, not all_states))
            return
    if analysis["explain"] is not None:
        prism_explain(model, constants, analysis["explain"], analysis["top"], as_json)
        return
    with user_errors(), build_progress(plain=True) as progress:
        run = check_prism_file(
            model, props_source=props, selectors=selectors, constants=constants,
            progress=limited(progress, max_states), exact=exact, keep="answers",
            # --simulate -o writes every structure's totals along the paths, and an
            # induced export every structure of the model
            rewards="all" if (analysis["simulate"] is not None
                              or analysis["induced_dir"] is not None) else "named",
            before_build=hopeless_export_check(analysis),
            # a strategy, an induced DTMC and simulated paths cover every state
            stop_early=not all_states and analysis["strategy_file"] is None
            and analysis["induced_dir"] is None and analysis["simulate"] is None,
        )
    print_warnings(run.warnings)
    print_imprecise(run.results)
    errors = getattr(run, "errors", ())
    if not errors:
        export_run_strategy(run, analysis)
    if analysis["simulate"] is not None:
        if not isinstance(run, ModelCheckRunType):
            with user_errors():
                raise OptionError("--simulate needs a DTMC model (this is an MDP)")
            return
        prism_simulate(run, model, constants, analysis["simulate"], seed=analysis["seed"],
                       max_steps=analysis["max_steps"], paths_file=analysis["paths_file"],
                       path_count=analysis["path_count"], output_format=output_format)
        return
    if output_format == "json":
        click.echo(json.dumps(prism_json(run)))
    elif output_format == "csv":
        print_prism_csv(run)
    else:
        print_prism_run(run)
    if errors:  # after the values PRISM would print (an infeasible multi's NaN, ...)
        fail(*errors)


def _check_modes(analysis: dict[str, Any]) -> None:
    """Refuse ``--explain`` with ``--simulate`` (one would be dropped), and an option of a
    mode that is not asked for (it would be ignored)."""
    if analysis["explain"] is not None and analysis["simulate"] is not None:
        raise OptionError("--explain and --simulate are separate runs: give one of them")
    check_modes({
        "--explain": (analysis["explain"] is not None, ("top",)),
        "--simulate": (analysis["simulate"] is not None, ("seed", "max_steps", "path_count")),
        "-o": (analysis["paths_file"] is not None, ("path_count",)),
    })


def _check_explain(explain: str | None, given: dict[str, bool]) -> None:
    """Refuse, with ``--explain``, the options of a check (*given*: whether each is): the
    breakdown reads the model's label, not properties, and builds every state."""
    if explain is None:
        return
    for option, present in given.items():
        if present and option == "--max-states":
            raise OptionError("--max-states: --explain builds the whole model, with no "
                              "limit; leave out --max-states")
        if present:
            raise OptionError(f"{option}: --explain checks no properties; leave out "
                              f"{option} or --explain")


def _experiment(model: Path, props: Path | None, selectors: tuple[str, ...],
                points: list[dict[str, str]], output_format: str, exact: bool,
                limits: tuple[int | None, bool]) -> None:
    """Every point of ``--const`` ranges checked, then printed together (*limits*:
    ``--max-states``, and whether exploration may stop where the properties are decided)."""
    max_states, stop_early = limits
    from veribattery.pipeline import check_prism_file

    runs = []
    for point in points:
        with user_errors(), build_progress(plain=True) as progress:
            runs.append(check_prism_file(
                model, props_source=props, selectors=selectors, constants=point,
                progress=limited(progress, max_states), exact=exact, keep="answers",
                stop_early=stop_early))
        errors: tuple[str, ...] = getattr(runs[-1], "errors", ())
        if errors:
            fail(*errors)
    print_experiment(points, runs, output_format, lambda r: (_labelled(r), _shown(r)),
                     prism_json, csv_rows)


def _format(output_format: str | None, as_json: bool) -> str:
    """``--format``, with ``--json`` as its old spelling (both given must agree)."""
    if as_json and output_format not in (None, "json"):
        raise OptionError(f"--json and --format {output_format} ask for different outputs; "
                          "give one of them")
    return "json" if as_json else output_format or "table"


def print_prism_csv(run: ModelCheckRun | MdpCheckRun) -> None:
    """``property,name,value,lower,upper,exact`` rows, values with full precision."""
    import csv
    import sys

    writer = csv.writer(sys.stdout, lineterminator="\n")
    writer.writerow(["property", "name", "value", "lower", "upper", "exact"])
    writer.writerows(csv_rows(run))


def csv_rows(run: ModelCheckRun | MdpCheckRun) -> list[list[str]]:
    """The CSV rows of *run*'s results (:func:`print_prism_csv`'s, without the header)."""
    rows = []
    for result in run.results:
        bounds = result_bounds(result) or ["", ""]
        value = UNDECIDED if _undecided(result) is not None else _csv_value(result.value)
        rows.append([result.property.text, result.property.name or "", value,
                     *map(_csv_value, bounds), exact_text(result) or ""])
    return rows


def _csv_value(value: object) -> str:
    if isinstance(value, bool):
        return format_value(value)
    return repr(value) if isinstance(value, float) else str(value)


def prism_json(run: ModelCheckRun | MdpCheckRun) -> dict[str, object]:
    """The ``prism --json`` document."""
    return {
        "model": run.model_summary,
        "results": [_result_json(r) for r in run.results],
        "timings_s": {k: round(v, 6) for k, v in run.timings_s.items()},
    }


def _result_json(result: CheckResult) -> dict[str, object]:
    """One result: property (and its name, if it has one), value (null, with the reason
    under ``undecided``, for a bound left undecided), ``exact`` under ``--exact``, for
    numbers the certified bounds and whether they meet the precision
    (``"certified": false`` when the answer has no certificate, e.g. ``multi(...)``),
    plus the range over several initial states and the states a print/argmin/argmax
    filter listed."""
    entry: dict[str, object] = {"property": result.property.text}
    if result.property.name is not None:
        entry["name"] = result.property.name
    reason = _undecided(result)
    entry["value"] = property_value(result.value) if reason is None else None
    if reason is not None:
        entry["undecided"] = reason
    exact = exact_text(result)
    if exact is not None:
        entry["exact"] = exact
    bounds = result_bounds(result)
    if bounds is not None:
        entry["bounds"] = bounds
        entry["precise"] = result.precise
    if not result.certified:  # a floating-point answer: bounds estimate, not enclose
        entry["certified"] = False
    if result.value_range is not None:
        entry["range"] = [property_value(v) for v in result.value_range]
    if result.printed:
        entry["states"] = list(result.printed)
    return entry


#: How a property is shown whose bound neither floats nor exact arithmetic decided.
UNDECIDED = "undecided"


def _undecided(result: CheckResult) -> str | None:
    """Why *result* is undecided (an :class:`~veribattery.checker.UndecidedResult`), or None."""
    from veribattery.checker import UndecidedResult  # loaded already: the run made it

    return result.reason if isinstance(result, UndecidedResult) else None


def _shown(result: CheckResult) -> str:
    """The value as PRISM reports it: ``[low, high]`` for a range, ``undecided``, else
    :func:`format_result` (``value ± error`` or ``p/q ≈ value``)."""
    if _undecided(result) is not None:
        return UNDECIDED
    if result.value_range is not None:
        low, high = result.value_range
        return f"[{format_value(low)}, {format_value(high)}]"
    return format_result(result)


def _labelled(result: CheckResult) -> str:
    """The property as written in a properties file: ``"name": formula``."""
    name = result.property.name
    return result.property.text if name is None else f'"{name}": {result.property.text}'


def print_prism_run(run: ModelCheckRun | MdpCheckRun) -> None:
    """Model size, then one table row per property."""
    size = run.model_summary
    choices = f"{size['choices']:,} choices, " if "choices" in size else ""
    click.echo(
        f"Model: {size['states']:,} states, {choices}{size['transitions']:,} transitions, "
        f"{size['initial_states']:,} initial, {size['deadlocks']:,} deadlocks"
    )
    stopped = size.get("stopped_states", 0)
    if stopped:
        print_dim(fit_text(f"{count_of(stopped, 'state')} left unexpanded: every property "
                           "is decided there (--all-states)"))
    rows = [(_labelled(result), _shown(result)) for result in run.results]
    print_table(("property", "value"), rows)
    for note in exact_notes(value for _, value in rows):
        print_dim(fit_text(note))
    for result in run.results:
        if result.printed:
            click.echo(f"States of {result.property.text}:")
            for line in result.printed:
                click.echo(f"  {line}")
    print_timings(run.timings_s)
