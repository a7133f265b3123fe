"""The mission commands: ``check`` a config and ``emit`` its PRISM files."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click

from veribattery.cli.files import PathParam, check_output_dir
from veribattery.cli.output import (
    build_progress,
    escape,
    exact_notes,
    exact_text,
    format_result,
    format_value,
    json_value,
    out,
    print_dim,
    print_imprecise,
    print_timings,
    print_warnings,
    print_written,
    result_bounds,
    set_option,
    user_errors,
)
from veribattery.cli.progress import limited
from veribattery.cli.tables import fit_text, print_table
from veribattery.errors import OptionError

if TYPE_CHECKING:
    from veribattery.config import MissionConfig
    from veribattery.mission import MissionFiles, MissionReport


@click.command("check", short_help="Verify a mission config; exit 1 if a requirement fails.")
@click.argument("config", type=PathParam(path_type=Path))
@set_option
@click.option(
    "--format", "output_format", type=click.Choice(["table", "json", "csv"]), default="table",
    show_default=True, help="Output format.",
)
@click.option(
    "--emit", "emit_dir", type=PathParam(path_type=Path), help="Also write the model files here."
)
@click.option("--force", is_flag=True, help="Let --emit overwrite existing files.")
@click.option(
    "--exact", is_flag=True,
    help="Compute in exact rational arithmetic; results as p/q, requirements decided exactly.",
)
@click.option(
    "--max-states", type=click.IntRange(min=1), default=None, metavar="N",
    help="Stop the build (exit 2) once more than N states are found.",
)
def check_command(
    config: Path, overrides: tuple[str, ...], output_format: str, emit_dir: Path | None,
    force: bool, exact: bool, max_states: int | None,
) -> None:
    """Verify the mission of CONFIG (YAML); exit 1 if a requirement fails."""
    from veribattery.config import load_config
    from veribattery.mission import EMITTED_FILES, check_mission, mission_files, write_files

    written: tuple[Path, ...] = ()
    with user_errors():
        if emit_dir is not None:
            check_output_dir(emit_dir, "--emit", force=force, names=EMITTED_FILES)
        elif force:
            raise OptionError("--force lets --emit overwrite its files: give --emit DIR, or "
                              "leave out --force")
        cfg = load_config(config, overrides)
        with build_progress(plain=True) as progress:
            report = check_mission(cfg, progress=limited(progress, max_states), exact=exact,
                                   keep="answers")
        if emit_dir is not None:
            written = write_files(mission_files(cfg), emit_dir, force=force)
    print_written(*written)
    print_warnings(report.warnings)
    print_imprecise(report.run.results)
    {"table": print_mission_table, "json": print_mission_json, "csv": print_mission_csv}[
        output_format
    ](report)
    sys.exit(0 if report.all_requirements_hold else 1)


def print_mission_table(report: MissionReport) -> None:
    """Model size, named results, requirements, timings."""
    dtmc = report.run.dtmc
    click.echo(f"Model: {dtmc.num_states:,} states, {dtmc.num_transitions:,} transitions")
    rows = [((result.property.name or "") + (" †" if is_conditional(result.property.formula)
                                              else ""),
             format_result(result), result.property.text) for result in report.run.results]
    print_table(("property", "value", "formula"), rows)
    notes = exact_notes(value for _, value, _ in rows)
    if any(is_conditional(r.property.formula) for r in report.run.results):
        notes.append("† conditional: the expectation given the condition after || "
                     "(e.g. given success)")
    for note in notes:
        print_dim(fit_text(note))
    for outcome in report.requirements:
        verdict = "[green]PASS[/]" if outcome.holds else "[bold red]FAIL[/]"
        if not outcome.decided:
            verdict = "[bold red]UNDECIDED[/] (precision not enough: the certified interval " \
                "straddles the bound)"
        out.print(f"{verdict} {escape(str(outcome.requirement))} "
                  f"(value {format_value(outcome.value)})")
    print_timings(report.run.timings_s)


def is_conditional(formula: object) -> bool:
    """Whether *formula* is a conditional (``||``) P or R query."""
    from veribattery.mission import is_conditional as conditional

    return conditional(formula)


def mission_json(report: MissionReport) -> dict[str, object]:
    """The ``check --format json`` document."""
    from veribattery.config.schema import RECHARGE_CAP_PROPERTY

    dtmc = report.run.dtmc
    return {
        "model": {"states": dtmc.num_states, "transitions": dtmc.num_transitions},
        "results": {name: json_value(value) for name, value in report.values.items()},
        "bounds": {r.property.name or r.property.text: result_bounds(r)
                   for r in report.run.results if result_bounds(r) is not None},
        "precise": {r.property.name or r.property.text: r.precise for r in report.run.results},
        "conditional": [r.property.name or r.property.text for r in report.run.results
                        if is_conditional(r.property.formula)],
        "requirements": [
            {**o.as_dict(), "value": json_value(o.value)} for o in report.requirements
        ],
        "timings_s": {k: round(v, 6) for k, v in report.run.timings_s.items()},
        **_exact_json(report),
        RECHARGE_CAP_PROPERTY: report.recharge_cap_probability,
    }


def _exact_json(report: MissionReport) -> dict[str, object]:
    """``{"exact": {name: "p/q"}}`` for an ``--exact`` run (numeric results only), else {}."""
    exact = {
        r.property.name or r.property.text: text
        for r in report.run.results
        if (text := exact_text(r)) is not None
    }
    return {"exact": exact} if exact else {}


def print_mission_json(report: MissionReport) -> None:
    """One JSON object on stdout."""
    click.echo(json.dumps(mission_json(report)))


def print_mission_csv(report: MissionReport) -> None:
    """``property,value`` rows (values with full precision; ``exact`` too under ``--exact``),
    then P[F rc=RC_MAX]."""
    from veribattery.config.schema import RECHARGE_CAP_PROPERTY

    exact = [exact_text(r) for r in report.run.results]
    with_exact = any(e is not None for e in exact)
    click.echo("property,value,exact" if with_exact else "property,value")
    for (name, value), text in zip(report.values.items(), exact, strict=True):
        shown = format_value(value) if isinstance(value, bool) else repr(value)
        click.echo(f"{name},{shown},{text or ''}" if with_exact else f"{name},{shown}")
    cap = repr(report.recharge_cap_probability)
    click.echo(f"{RECHARGE_CAP_PROPERTY},{cap}," if with_exact
               else f"{RECHARGE_CAP_PROPERTY},{cap}")
    for outcome in report.requirements:  # stdout stays CSV: why the exit is 1, on stderr
        if not outcome.holds:
            verdict = "FAIL" if outcome.decided else "UNDECIDED"
            click.echo(f"{verdict} {outcome.requirement} (value {format_value(outcome.value)})",
                       err=True)


@click.command("emit", short_help="Write a config's PRISM model and properties.")
@click.argument("config", type=PathParam(path_type=Path))
@click.option("-o", "--output", "out_dir", type=PathParam(path_type=Path), required=True,
              help="Directory for model.prism, properties.props (PRISM and Storm), "
                   "storm-only.props (Storm only), config.resolved.yaml.")
@set_option
@click.option("--force", is_flag=True, help="Overwrite existing files.")
def emit_command(config: Path, out_dir: Path, overrides: tuple[str, ...], force: bool) -> None:
    """Write the PRISM model and properties of CONFIG for PRISM or Storm.

    With strategy.mode: synthesize, the model is the mission's MDP and the properties
    are its questions: the best P(success), and the fastest policy for each requirement
    on P(success).
    """
    from veribattery.config import load_config
    from veribattery.mission import EMITTED_FILES, write_files

    warnings: tuple[str, ...] = ()
    with user_errors():
        check_output_dir(out_dir, "-o", force=force, names=EMITTED_FILES)
        cfg = load_config(config, overrides)
        if cfg.strategy.mode == "synthesize":
            from veribattery.synthesis import synthesis_files, unasked_requirements

            files, warnings = synthesis_files(cfg), unasked_requirements(cfg)
        else:
            files = _checked_mission_files(cfg)
        written = write_files(files, out_dir, force=force)
    print_warnings(warnings)
    for path in written:
        click.echo(str(path))


def _checked_mission_files(cfg: MissionConfig) -> MissionFiles:
    """BS1's files, valid for our own front end before they are written."""
    from veribattery.lang import flatten_model, parse_model, parse_properties
    from veribattery.mission import MODEL_FILE, PROPERTIES_FILE, mission_files

    files = mission_files(cfg)
    flatten_model(parse_model(files.model, name=MODEL_FILE))
    parse_properties(files.properties, name=PROPERTIES_FILE)
    return files

