"""What the battery prognostics commands print: tables, JSON, CSV and the YAML fragments
of ``phm fade|levels|forecast`` and ``recheck`` (:mod:`.phm`), and the errors on bad
input that need more than a sentence: each names the option or key at fault and says
what works for the command at hand."""

from __future__ import annotations

import csv
import io
import json
import math
import os
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
from veribattery.errors import OptionError

if TYPE_CHECKING:
    from veribattery.config import MissionConfig
    from veribattery.errors import ConfigError
    from veribattery.phm.fade import FadeReport
    from veribattery.phm.forecast import Forecast
    from veribattery.phm.fragment import Fragment
    from veribattery.phm.levels import SocGridError, StepFit
    from veribattery.phm.recheck import Recheck
    from veribattery.phm.refit import (
        BeyondDataError,
        FadeParameters,
        LevelParameters,
        RechargeCapError,
    )

__all__ = [
    "CONFIG_REMEDY",
    "CYCLES_REMEDY",
    "DISCHARGE_REMEDY",
    "WRITE_REMEDY",
    "check_input_file",
    "check_links",
    "file_remedy",
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
    "recharge_cap_error",
    "set_remedy",
    "soc_grid_error",
    "too_far",
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


#: What to give an option that names a file that is not there.
CYCLES_REMEDY = "give the path of the capacity log (cycle,capacity_ah)"
DISCHARGE_REMEDY = ("give the path of the discharge log (soc,voltage_v or "
                  "time_s,voltage_v,current_a)")
CONFIG_REMEDY = "give an existing config (leave --config out for the paper's)"
WRITE_REMEDY = ("--write merges into an existing config: create it first (an empty file is "
              "the paper's config), or leave --write out and paste the fragment printed")


def check_input_file(path: str | Path | None, option: str, remedy: str) -> None:
    """Before any work: *option*'s file must be there and readable, else an error that
    names the option (the reader's own said only "cannot read FILE")."""
    if path is None:
        return
    where = Path(path)
    if where.is_dir():
        raise OptionError(f"{option} {path}: is a folder; name a file in it")
    if not where.exists():
        raise OptionError(f"{option} {path}: no such file; {remedy}")
    if not os.access(where, os.R_OK):
        raise OptionError(f"{option} {path}: not readable (permission denied); {remedy}")


def check_links(write: Path | None) -> None:
    """Before any work: --write replaces the file by a new one (all or nothing), which
    would split a file with several hard links (the other names keep the old config)."""
    from veribattery.phm.merge import hard_links

    links = 0 if write is None else hard_links(write)
    if links > 1:
        raise OptionError(f"--write {write}: the file has {links} hard links, and --write "
                          "replaces it by a new file, which would split them; give a file "
                          "with one name (a symbolic link to it is followed), or merge the "
                          "fragment by hand")


def too_far(option: str, typed: str, exc: BeyondDataError,
            largest: float | None) -> OptionError:
    """*exc* blamed on *option*: it asks for a cycle further ahead than the fit reaches
    (*largest*: the option's largest value that works; None: no value works)."""
    works = (f"the largest {option} that works is {largest:.15g}" if largest is not None else
             "the fit is usable at the log's last cycle only")
    return OptionError(f"{option} {typed}: too far beyond the log's last cycle {exc.last:g}: "
                       f"{exc.reason}; {works}")


def recharge_cap_error(cfg: MissionConfig, exc: RechargeCapError, remedy: str) -> ConfigError:
    """*exc* placed on battery.max_recharges where *cfg* got it (its --set, its line in
    the file), rather than on a row of the log: the key is what to change."""
    return cfg.key_error(("battery.max_recharges", f"{exc.problem}; {remedy}"))


def set_remedy(exc: RechargeCapError) -> str:
    """How recheck and forecast, which take --set, fix a clash with battery.max_recharges."""
    return (f"battery.max_recharges must be at most {exc.largest}, e.g. "
            f"--set battery.max_recharges={exc.largest}")


def file_remedy(exc: RechargeCapError, source: Path | None) -> str:
    """How phm fade, which has no --set, fixes it: in its config file *source* (None:
    the paper's config, used without --config and --write)."""
    setting = f"battery.max_recharges: {exc.largest}"
    if source is not None:
        return f"set {setting} or less in {source}"
    return (f"give --config (or --write) a config with {setting} or less (without them, "
            "the paper's config is used)")


def soc_grid_error(exc: SocGridError, charge_ah: float | None, capacity_ah: str | None,
                   soc_step: str) -> OptionError | None:
    """*exc* blamed on the option that set the grid, as typed: --soc-step when it is too
    fine, --capacity-ah (when given; *charge_ah*: what the log delivers) when the SOC
    range is too narrow for it; None when the log itself is at fault."""
    from veribattery.phm.levels import MAX_GRID

    if exc.too_fine:
        least = _two_digits((exc.highest - exc.lowest) / MAX_GRID, up=True)
        return OptionError(
            f"--soc-step {soc_step}: puts more than {MAX_GRID:,} grid points on the log's SOC "
            f"range {exc.lowest:.3g}..{exc.highest:.3g}; give a step of at least {least:g}, "
            "e.g. 0.01")
    if capacity_ah is None or charge_ah is None:
        return None
    step = float(exc.step)
    return OptionError(
        f"--capacity-ah {capacity_ah}: the log delivers {charge_ah:.4g} Ah, only "
        f"{charge_ah / float(capacity_ah):.2g} of that, so its SOC spans fewer than 3 points "
        f"of the {step:g} SOC grid; give the battery's full charge (at most "
        f"{_two_digits(charge_ah / (2 * step), up=False):g} Ah for this log), or leave it "
        f"out to use the {charge_ah:.4g} Ah the log delivers")


def _two_digits(value: float, up: bool) -> float:
    """*value* > 0 to two significant digits, rounded up or down: a bound printed
    rounded to nearest may be just past the values that work."""
    scale = 10.0 ** (math.floor(math.log10(value)) - 1)
    return (math.ceil if up else math.floor)(value / scale) * scale
