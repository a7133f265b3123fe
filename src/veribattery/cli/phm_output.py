"""What the battery prognostics commands print: tables, JSON, CSV and the YAML fragments
of ``phm fade|levels|forecast`` and ``recheck`` (:mod:`.phm`)."""

from __future__ import annotations

import csv
import io
import json
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from veribattery.cli.output import (
    escape,
    format_value,
    json_value,
    out,
    print_written,
)
from veribattery.cli.tables import fit_text, print_table

if TYPE_CHECKING:
    from veribattery.phm.fade import FadeReport
    from veribattery.phm.forecast import Forecast
    from veribattery.phm.fragment import Fragment
    from veribattery.phm.levels import StepFit
    from veribattery.phm.recheck import Recheck
    from veribattery.phm.refit import FadeParameters, LevelParameters

__all__ = [
    "files_written",
    "print_fade",
    "print_files",
    "print_fits",
    "print_forecast",
    "print_forecast_csv",
    "print_fragment",
    "print_json",
    "print_levels",
    "print_recheck",
]


def print_fragment(fragment: Fragment) -> None:
    """The YAML fragment (also when --write merged it: it is the result)."""
    out.print("\n# YAML fragment for the mission config:", style="bold", markup=False)
    click.echo(fragment.yaml(), nl=False)


def print_files(*paths: Path | None) -> None:
    """The files written (figure, merged config), as every command lists them: ``wrote
    FILE`` on stderr, whatever the format (stdout carries only the results)."""
    print_written(*(path for path in paths if path is not None))


def print_json(document: dict[str, object]) -> None:
    click.echo(json.dumps(_json_ready(document)))


def _json_ready(value: object) -> object:
    """*value* as JSON: exact config values as numbers, infinities as strings."""
    from fractions import Fraction

    if isinstance(value, dict):
        return {str(key): _json_ready(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_json_ready(item) for item in value]
    return json_value(float(value) if isinstance(value, Fraction) else value)


def files_written(fragment: Fragment, plot: Path | None, write: Path | None
                   ) -> dict[str, object]:
    """The JSON keys of what fade and levels wrote (or would have the user paste)."""
    return {"fragment_yaml": fragment.yaml(), "figure": None if plot is None else str(plot),
            "merged_into": None if write is None else str(write)}


def print_fits(report: FadeReport) -> None:
    rows = [(fit.name, f"{fit.aic:.2f}", f"{fit.rmse:.4g}", f"{abs(fit.residuals).max():.4g}")
            for fit in report.fits]
    print_table(("model", "AIC", "RMSE (Ah)", "max |resid| (Ah)"), rows)
    for fit in report.fits:
        values = ", ".join(f"{k}={v:.6g}" for k, v in fit.params.items())
        _item(f"{fit.name}: {fit.formula}; {values}")
    for name, why in report.skipped.items():
        _item(f"{name}: not used ({why})", style="dim")
    out.print(f"choice: {report.explanation()}", markup=False)


def _item(text: str, style: str | None = None) -> None:
    """*text* as an item of a list, indented by 2. On a terminal, where long lines wrap,
    its continuation lines are indented by 4: rich wrapped them to column 0, where they
    read as lines of their own. Off a terminal it stays one line, as every message."""
    line = f"  {text}"
    if out.is_terminal:
        line = fit_text(line, out.width, indent="    ")
    out.print(line, style=style, markup=False)


def print_fade(params: FadeParameters) -> None:
    fit = params.fit
    resid = ", ".join(f"{r:+.3g}" for r in fit.residuals[:12])
    more = " …" if len(fit.residuals) > 12 else ""
    out.print(f"residuals of {fit.name} (Ah, first rows): {resid}{more}", markup=False)
    low, high = params.fade_ci
    out.print(f"at cycle {params.at_cycle:g}: capacity {params.capacity_fit_ah:.4f} Ah "
              f"(on the grid: {_show(params.capacity_ah)} Ah), "
              f"loss {fit.loss_per_cycle(params.at_cycle):.4g} Ah/cycle, "
              f"fade {params.fade:.4g}/cycle, 95% CI [{low:.4g}, {high:.4g}]", markup=False)


def print_levels(params: LevelParameters, paper: StepFit | None) -> None:
    steps = params.steps
    low, high = _show(steps.low), _show(steps.high)
    say = partial(out.print, markup=False)
    say(f"thresholds: low SOC < {low}, medium {low}..{high}, high SOC > {high}")
    named = zip(("low", "medium", "high"), params.voltages_v, strict=True)
    say("levels: " + ", ".join(f"{n} {_show(v)} V" for n, v in named))
    say(f"approximation error on the SOC grid: RMS {steps.rms_v:.4g} V, "
        f"max {steps.max_v:.4g} V (minimised over all threshold pairs)")
    if paper is not None:
        say(f"(the config's thresholds {_show(paper.low)}/{_show(paper.high)} would give RMS "
            f"{paper.rms_v:.4g} V, max {paper.max_v:.4g} V)")
    rows = [(action, wind, *map(str, row)) for action, table in params.table.items()
            for wind, row in zip(("low", "high"), table, strict=True)]
    print_table((f"action (units of {_show(params.resolution)} Ah)", "wind", "low V",
                 "medium V", "high V"), rows, keys=2,
                title="Eq. 2 consumption, C = E_spec·t / (V·T), rounded half up:")


def print_forecast(result: Forecast, shown: list[str]) -> None:
    req = result.requirement
    rows = [[str(p.ahead), f"{result.now + p.ahead:g}", _show(p.capacity_ah), _show(p.fade),
             *(_short(p.values[name]) for name in shown), "yes" if p.holds else "no"]
            for p in result.points]
    print_table(["ahead", "cycle", "capacity_ah", "fade", *shown, "holds"], rows)
    say = partial(out.print, markup=False)
    if result.fails_after is None:
        last = result.points[-1].ahead
        say(f"{req} holds at every checked age up to {last} cycles ahead")
    elif result.fails_after == 0:
        say(f"{req} already fails now (cycle {result.now:g})")
    else:
        say(f"{req} stops holding after {result.fails_after} more cycles "
            f"(cycle {result.now + result.fails_after:g}; located by bisection between "
            "the checked ages, assuming one crossing between them)")


def print_forecast_csv(result: Forecast, shown: list[str]) -> None:
    """The table's rows as CSV, numbers in full (exact config values as decimals)."""
    stream = io.StringIO()
    writer = csv.writer(stream, lineterminator="\n")
    writer.writerow(["ahead", "cycle", "capacity_ah", "fade_per_recharge", *shown, "holds"])
    for p in result.points:
        writer.writerow([p.ahead, format_value(result.now + p.ahead), _show(p.capacity_ah),
                         _show(p.fade), *(_csv_value(p.values[name]) for name in shown),
                         format_value(p.holds)])
    click.echo(stream.getvalue(), nl=False)


def _csv_value(value: object) -> str:
    return format_value(value) if isinstance(value, bool) else repr(value)


def print_recheck(result: Recheck, document: dict[str, Any]) -> None:
    out.print("parameters moved by the refit ('-': not set that way before):", style="bold",
              markup=False)
    for moved in result.moved:
        before = "-" if moved.before is None else _show(moved.before)
        _item(f"{moved.key}: {before} → {_show(moved.after)}")
    if not result.moved:
        _item("none")
    rows = [(str(name), format_value(row["before"]), format_value(row["after"]),
             "" if row["change"] is None else f"{row['change']:+.6g}")
            for name, row in document["properties"].items()]
    print_table(("property", "before", "after", "change"), rows)
    _print_requirements(result)


def _print_requirements(result: Recheck) -> None:
    before = {str(o.requirement): o.holds for o in result.before.requirements}
    for outcome in result.after.requirements:
        name = str(outcome.requirement)
        was = "PASS" if before.get(name) else "FAIL"
        now = "[green]PASS[/]" if outcome.holds else "[bold red]FAIL[/]"
        out.print(f"{escape(name)}: before {was}, after {now}")
    if result.regressions:
        out.print(f"[bold red]no longer holds:[/] {escape(', '.join(result.regressions))}")


def _short(value: object) -> str:
    """A value to 6 significant digits, for narrow tables."""
    return f"{value:.6g}" if isinstance(value, float) else format_value(value)


def _show(value: object) -> str:
    from fractions import Fraction

    from veribattery.config.exact import show

    return show(value) if isinstance(value, Fraction | str | tuple | list) else str(value)
