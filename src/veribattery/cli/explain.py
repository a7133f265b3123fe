"""``veribattery explain`` and ``prism --explain``: where failures come from.

The exact breakdown of a target's probability over the states it is entered from,
and the most probable paths to it.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import click

from veribattery._text import count_of
from veribattery.cli.analysis_options import (
    MOST_PATHS,
    counted,
    induced_mission,
    strategy_option,
)
from veribattery.cli.files import (
    CSV_SUFFIXES,
    OnceOption,
    PathParam,
    check_output_file,
    typed_name,
)
from veribattery.cli.output import (
    build_progress,
    fail,
    format_value,
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
    from veribattery.config import MissionConfig
    from veribattery.explore import DTMC
    from veribattery.lang import FlatModel
    from veribattery.lang.nodes import Value
    from veribattery.pipeline import ProgressCallback

__all__ = ["FAILURE_NOTES", "explain_command", "failure_notes", "prism_explain"]

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


def _groupings(ctx: click.Context, param: click.Parameter,
               by: Sequence[str]) -> tuple[tuple[str, ...], ...]:
    """An option callback: ``--by cell,wind --by k+cell`` → ``(("cell",), ("wind",),
    ("k", "cell"))``. An empty grouping or key, a key twice in one grouping, a grouping
    asked for twice or a key the mission lacks is bad input, on one line (exit 2)."""
    from veribattery.analyses.mission_view import GROUP_KEYS

    groupings: list[tuple[str, ...]] = []
    for value in by:
        for item in value.split(","):
            keys = tuple(key.strip() for key in item.split("+"))
            problem = _grouping_problem(item, keys, groupings, GROUP_KEYS)
            if problem is not None:
                fail(f"--by {value if value.strip() else repr(value)}: {problem}; give "
                     f"keys comma-separated, a+b to group by both (keys: "
                     f"{', '.join(GROUP_KEYS)})")
            groupings.append(keys)
    return tuple(groupings)


def _grouping_problem(item: str, keys: tuple[str, ...], earlier: Sequence[tuple[str, ...]],
                      known: Sequence[str]) -> str | None:
    """What is wrong with the grouping *item* (its *keys*), or None."""
    if not item.strip():
        return "an empty grouping"
    if "" in keys:
        return f"an empty key in {item.strip()!r}"
    unknown = next((key for key in keys if key not in known), None)
    if unknown is not None:
        return f"no key {unknown!r}"
    twice = next((key for key in keys if keys.count(key) > 1), None)
    if twice is not None:
        return f"{twice} twice in {item.strip()}"
    if any(set(keys) == set(other) for other in earlier):
        return f"the grouping {item.strip()} is asked for twice"
    return None


# ---------------------------------------------------------------------------
# explain
# ---------------------------------------------------------------------------


@click.command("explain", short_help="Where failures come from: breakdown and paths.")
@click.argument("config", type=PathParam(path_type=Path))
@set_option
@click.option("--top", default=3, show_default=True, callback=counted("--top", MOST_PATHS),
              help="How many most probable failure paths.")
@click.option("--by", "by", multiple=True, metavar="KEYS", callback=_groupings,
              help="Groupings, comma-separated; join keys with + for a joint grouping "
                   "(keys: k, cell, state, action, wind, level, recharges, or a variable).")
@click.option("-o", "--output", "--csv", "csv_file", cls=OnceOption,
              type=PathParam(path_type=Path),
              help="Write the paths here as CSV, one row per step (--csv: the old name).")
@click.option("--force", is_flag=True, help="Overwrite an existing -o file.")
@click.option("--format", "output_format", type=click.Choice(["table", "json"]),
              default="table", show_default=True, help="Output format.")
@strategy_option
def explain_command(config: Path, overrides: tuple[str, ...], top: int,
                    by: tuple[tuple[str, ...], ...],
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
        check_output_file(csv_file, typed_name("csv_file", "-o"), force=force,
                          suffixes=CSV_SUFFIXES)
        cfg = load_config(config, overrides)
        with build_progress() as progress:
            view = (MissionView(build_mission(cfg, progress=progress)) if strategy == "bs1"
                    else _strategy_view(cfg, strategy, progress))
        explanation = explain_target(
            view.dtmc, view.dtmc.labels["failure"], name="failure",
            describe=view.columns, by=by or DEFAULT_GROUPINGS, top=top,
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
    for note in failure_notes(_shown_actions(explanation, steps)):
        print_dim(fit_text(note))


def _strategy_view(cfg: MissionConfig, strategy: str,
                   progress: ProgressCallback | None) -> MissionView:
    """The mission under the strategy ``--strategy`` names, in the paper's terms."""
    from veribattery.analyses.mission_view import MissionModel
    from veribattery.analyses.strategy_view import StrategyView
    induced = induced_mission(cfg, strategy, progress)
    return StrategyView(MissionModel(cfg, induced.flat, induced.dtmc), induced.actions)


#: What the mission's ways of failing mean, under the tables that show them: by the test
#: an action shown passes, its note (``oob (take-off)`` is the one, ``abort`` the other).
FAILURE_NOTES: tuple[tuple[Callable[[str], bool], str], ...] = (
    (lambda action: action.startswith("oob (") and action != "oob (recharge cap)",
     "oob (X): out of battery: the drone could not pay for X (take-off, flight, inspection, "
     "landing) and the mission failed."),
    (lambda action: action == "oob (recharge cap)",
     "oob (recharge cap): battery.max_recharges was reached with cells left."),
    (lambda action: action == "abort",
     "abort: the strategy gives the mission up there, and it fails."),
)


def failure_notes(actions: Iterable[str]) -> list[str]:
    """The notes of :data:`FAILURE_NOTES` for the *actions* shown, in that order: a note
    for an action that is not shown (``oob`` where only ``abort`` fails) misleads."""
    shown = set(actions)
    return [note for applies, note in FAILURE_NOTES if any(applies(a) for a in shown)]


def _shown_actions(explanation: Explanation,
                   steps: Sequence[Sequence[Mapping[str, object]]]) -> list[str]:
    """The actions the tables show: in the rows of a grouping by action, and the paths."""
    shown = [str(row["action"]) for rows in steps for row in rows]
    for grouping in explanation.groupings:
        if "action" in grouping.keys:
            at = grouping.keys.index("action")
            shown += [str(values[at]) for values, _ in grouping.groups[:GROUP_ROWS]]
    return shown


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
    entered_from = count_of(explanation.inflow.states.size, "state")
    click.echo(fit_text(
        f"P({explanation.target}) = {format_value(total)}  (exact; the breakdown sums to it "
        f"over the {entered_from} {explanation.target} is entered from)"))
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
# prism MODEL --explain LABEL
# ---------------------------------------------------------------------------


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


def _build_prism(model: Path, constants: Mapping[str, Value | str]) -> tuple[FlatModel, DTMC]:
    from veribattery.explore import build_dtmc
    from veribattery.lang import flatten_model, parse_model

    flat = flatten_model(parse_model(model), constants)
    return flat, build_dtmc(flat)
