"""The battery prognostics commands: ``phm fade|levels|simulate|forecast`` and ``recheck``."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

from veribattery.cli.output import format_value, out, print_warnings, set_option, user_errors

if TYPE_CHECKING:
    from veribattery.config import MissionConfig
    from veribattery.phm.fade import FadeReport
    from veribattery.phm.forecast import Forecast
    from veribattery.phm.recheck import Recheck
    from veribattery.phm.refit import FadeParameters, LevelParameters

F = TypeVar("F", bound=Callable[..., Any])

MODELS = click.Choice(["linear", "exponential", "knee"])


def _plot_option(function: F) -> F:
    return click.option("--plot", "plot_path", type=click.Path(path_type=Path),
                        help="Also write a PNG figure here (never over an existing file)."
                        )(function)


def _model_option(function: F) -> F:
    return click.option("--model", type=MODELS, default=None,
                        help="Use this fade model instead of the AIC choice.")(function)


def _new_file(path: Path | None) -> None:
    """Refuse to overwrite a user's file with a figure or CSV."""
    from veribattery.phm.data import PhmDataError

    if path is not None and path.exists():
        raise PhmDataError(f"{path}: already exists; remove it or choose another name")


def _base_config(config: Path | None, write: Path | None) -> MissionConfig:
    from veribattery.config import load_config

    source = write if write is not None else config
    return load_config(source) if source is not None else load_config("")


def _write_or_print(fragment_values: dict[str, object], yaml_text: str, write: Path | None) -> None:
    if write is None:
        out.print("\n# YAML fragment for the mission config:", style="bold")
        click.echo(yaml_text, nl=False)
        return
    from veribattery.config import load_config
    from veribattery.phm.merge import merge_text, write_atomic

    original = write.read_text(encoding="utf-8")
    merged = merge_text(original, fragment_values, str(write))
    load_config(merged + "\n")  # the merged config must validate before it replaces the file
    write_atomic(write, merged)
    out.print(f"\nmerged {', '.join(fragment_values)} into {write} (comments kept)")


@click.group("phm")
def phm_group() -> None:
    """Battery prognostics: model parameters from cycling data, discharge curves, physics."""


@phm_group.command("fade")
@click.argument("cycles", type=click.Path(path_type=Path))
@click.option("--at-cycle", type=float, default=None,
              help="Cycle the battery is at (default: the last logged cycle).")
@click.option("--config", type=click.Path(path_type=Path),
              help="Config for resolution_ah and max_recharges (default: the paper's).")
@click.option("--write", type=click.Path(path_type=Path),
              help="Merge battery.capacity_ah and fade_per_recharge into this config.")
@_model_option
@_plot_option
def fade_command(cycles: Path, at_cycle: float | None, config: Path | None, write: Path | None,
                 model: str | None, plot_path: Path | None) -> None:
    """Fit capacity fade per cycle in CYCLES.csv (cycle,capacity_ah)."""
    from veribattery.phm.data import read_cycles
    from veribattery.phm.refit import fade_parameters

    with user_errors():
        _new_file(plot_path)
        cfg = _base_config(config, write)
        log = read_cycles(cycles)
        params = fade_parameters(log, cfg, at_cycle, model)
        _print_fits(params.report)
        _print_fade(params)
        if plot_path is not None:
            from veribattery.phm.plot import plot_fade

            plot_fade(log, params, cfg.battery.max_recharges,
                      float(cfg.battery.resolution_ah), plot_path)
            out.print(f"figure: {plot_path}")
        _write_or_print(params.fragment.values, params.fragment.yaml(), write)


def _print_fits(report: FadeReport) -> None:
    from rich.table import Table

    table = Table("model", "AIC", "RMSE (Ah)", "max |resid| (Ah)", show_edge=False)
    for fit in report.fits:
        table.add_row(fit.name, f"{fit.aic:.2f}", f"{fit.rmse:.4g}",
                      f"{abs(fit.residuals).max():.4g}")
    out.print(table)
    for fit in report.fits:
        values = ", ".join(f"{k}={v:.6g}" for k, v in fit.params.items())
        out.print(f"  {fit.name}: {fit.formula}; {values}")
    for name, why in report.skipped.items():
        out.print(f"  {name}: not used ({why})", style="dim")
    out.print(f"choice: {report.explanation()}")


def _print_fade(params: FadeParameters) -> None:
    fit = params.fit
    resid = ", ".join(f"{r:+.3g}" for r in fit.residuals[:12])
    more = " …" if len(fit.residuals) > 12 else ""
    out.print(f"residuals of {fit.name} (Ah, first rows): {resid}{more}")
    low, high = params.fade_ci
    out.print(f"at cycle {params.at_cycle:g}: capacity {params.capacity_fit_ah:.4f} Ah "
              f"(on the grid: {_show(params.capacity_ah)} Ah), "
              f"loss {fit.loss_per_cycle(params.at_cycle):.4g} Ah/cycle, "
              f"fade {params.fade:.4g}/cycle, 95% CI [{low:.4g}, {high:.4g}]")


@phm_group.command("levels")
@click.argument("discharge", type=click.Path(path_type=Path))
@click.option("--capacity-ah", type=float, default=None,
              help="Q_max for Coulomb counting (default: the charge the log delivers).")
@click.option("--soc-step", type=str, default="0.01", show_default=True,
              help="SOC grid on which thresholds are chosen (exact decimal).")
@click.option("--config", type=click.Path(path_type=Path),
              help="Config for Eq. 2's energy, times and resolution_ah (default: the paper's).")
@click.option("--write", type=click.Path(path_type=Path),
              help="Merge voltage_thresholds and an Eq. 2 consumption into this config.")
@_plot_option
def levels_command(discharge: Path, capacity_ah: float | None, soc_step: str,
                   config: Path | None, write: Path | None, plot_path: Path | None) -> None:
    """Derive voltage levels, SOC thresholds (BA3) and consumption from a discharge curve."""
    from veribattery.phm.data import PhmDataError, read_discharge
    from veribattery.phm.levels import fixed_steps
    from veribattery.phm.refit import level_parameters

    with user_errors():
        _new_file(plot_path)
        step = _soc_step(soc_step)
        cfg = _base_config(config, write)
        curve = read_discharge(discharge, capacity_ah)
        params = level_parameters(curve, cfg, step)
        _print_levels(params)
        try:
            paper = fixed_steps(curve, cfg.battery.voltage_thresholds.low,
                                cfg.battery.voltage_thresholds.high, step)
            out.print(f"(the config's thresholds {_show(paper.low)}/{_show(paper.high)} "
                      f"would give RMS "
                      f"{paper.rms_v:.4g} V, max {paper.max_v:.4g} V)")
        except PhmDataError:  # the comparison is informative only
            pass
        if plot_path is not None:
            from veribattery.phm.plot import plot_levels

            plot_levels(params, plot_path)
            out.print(f"figure: {plot_path}")
        _write_or_print(params.fragment.values, params.fragment.yaml(), write)


def _soc_step(text: str) -> Any:
    from fractions import Fraction

    from veribattery.phm.data import PhmDataError

    try:
        step = Fraction(text)
    except (ValueError, ZeroDivisionError):
        raise PhmDataError(f"--soc-step: must be a decimal such as 0.01, got {text!r}") from None
    if not 0 < step <= Fraction(1, 10):
        raise PhmDataError(f"--soc-step: must be in (0, 0.1], got {text}")
    return step


def _print_levels(params: LevelParameters) -> None:
    from rich.table import Table

    steps = params.steps
    low, high = _show(steps.low), _show(steps.high)
    out.print(f"thresholds: low SOC < {low}, medium {low}..{high}, high SOC > {high}")
    named = zip(("low", "medium", "high"), params.voltages_v, strict=True)
    out.print("levels: " + ", ".join(f"{n} {_show(v)} V" for n, v in named))
    out.print(f"approximation error on the SOC grid: RMS {steps.rms_v:.4g} V, "
              f"max {steps.max_v:.4g} V (minimised over all threshold pairs)")
    table = Table(f"action (units of {_show(params.resolution)} Ah)", "wind",
                  "low V", "medium V", "high V", show_edge=False)
    for action, rows in params.table.items():
        for wind, row in zip(("low", "high"), rows, strict=True):
            table.add_row(action, wind, *map(str, row))
    out.print("Eq. 2 consumption, C = E_spec·t / (V·T), rounded half up:")
    out.print(table)


@phm_group.command("simulate")
@click.option("--parameter-set", default="Chen2020", show_default=True,
              help="PyBaMM parameter set (built in; nothing is downloaded).")
@click.option("--power-w", type=click.FloatRange(min=0, min_open=True), required=True,
              help="Constant pack power, W.")
@click.option("--cells-series", type=click.IntRange(min=1), default=1, show_default=True)
@click.option("--cells-parallel", type=click.IntRange(min=1), default=1, show_default=True)
@click.option("--cycles", type=click.IntRange(min=3), default=None,
              help="Also run an ageing experiment (SEI growth) of this many cycles.")
@click.option("--sei", type=click.Choice(["reaction limited", "solvent-diffusion limited",
                                          "ec reaction limited",
                                          "interstitial-diffusion limited"]),
              default="reaction limited", show_default=True,
              help="SEI growth submodel of the ageing experiment.")
@click.option("--period-s", type=click.FloatRange(min=1), default=30.0, show_default=True,
              help="Output time step of the discharge, s.")
@click.option("-o", "--output", "out_dir", type=click.Path(path_type=Path), default=Path("."),
              show_default=True, help="Directory for discharge.csv (and cycles.csv).")
@click.option("--force", is_flag=True, help="Overwrite existing CSVs.")
def simulate_command(parameter_set: str, power_w: float, cells_series: int,
                     cells_parallel: int, cycles: int | None, sei: str, period_s: float,
                     out_dir: Path,
                     force: bool) -> None:
    """Physics when there is no data: PyBaMM discharge (and ageing) CSVs."""
    from veribattery.phm.simulate import Pack, simulate, write_csvs

    with user_errors():
        pack = Pack(parameter_set, power_w, cells_series, cells_parallel, sei)
        argv = ["veribattery", "phm", "simulate", "--parameter-set", parameter_set,
                "--power-w", f"{power_w:g}", "--cells-series", str(cells_series),
                "--cells-parallel", str(cells_parallel)]
        if cycles:
            argv += ["--cycles", str(cycles), "--sei", sei]
        argv += ["--period-s", f"{period_s:g}", "-o", str(out_dir)]
        written = write_csvs(simulate(pack, cycles, period_s), out_dir, argv, force=force)
    for path in written:
        click.echo(str(path))


@phm_group.command("forecast")
@click.argument("config", type=click.Path(path_type=Path))
@click.option("--cycles", "cycles_path", type=click.Path(path_type=Path), required=True,
              help="Capacity log (cycle,capacity_ah).")
@click.option("--horizon", type=click.IntRange(min=1), default=300, show_default=True,
              help="Cycles ahead to look.")
@click.option("--step", type=click.IntRange(min=1), default=None,
              help="Cycles between checked ages (default: horizon/10; each age is one "
                   "mission check, ~1-2 s on the paper's farm).")
@click.option("--require", "requirement", default="p_success >= 0.99", show_default=True,
              help="The requirement whose end is forecast.")
@click.option("--time-property", default="exp_mission_time", show_default=True,
              help="Mission-time property to report and plot ('' for none).")
@_model_option
@set_option
@_plot_option
def forecast_command(config: Path, cycles_path: Path, horizon: int, step: int | None,
                     requirement: str, time_property: str, model: str | None,
                     overrides: tuple[str, ...], plot_path: Path | None) -> None:
    """P(success) and mission time as the battery ages; when does REQUIRE stop holding?"""
    from veribattery.config import parse_requirement
    from veribattery.phm.data import PhmDataError, read_cycles
    from veribattery.phm.forecast import forecast

    with user_errors():
        _new_file(plot_path)
        try:
            req = parse_requirement(requirement)
        except ValueError as exc:
            raise PhmDataError(f"--require: {exc}") from None
        log = read_cycles(cycles_path)
        result = forecast(config, log, req, horizon, step or max(1, horizon // 10), overrides,
                          model)
        _print_forecast(result, time_property)
        if plot_path is not None:
            from veribattery.phm.plot import plot_forecast

            plot_forecast(result, time_property or None, plot_path)
            out.print(f"figure: {plot_path}")


def _print_forecast(result: Forecast, time_property: str) -> None:
    from rich.table import Table

    req = result.requirement
    columns = ["ahead", "cycle", "capacity_ah", "fade", req.prop]
    shown = time_property if time_property and time_property != req.prop else ""
    table = Table(*columns, *([shown] if shown else []), "holds", show_edge=False)
    for p in result.points:
        extra = [_short(p.values.get(shown))] if shown else []
        table.add_row(str(p.ahead), f"{result.now + p.ahead:g}", _show(p.capacity_ah),
                      _show(p.fade), _short(p.values[req.prop]), *extra,
                      "yes" if p.holds else "[bold red]no[/]")
    out.print(table)
    if result.fails_after is None:
        last = result.points[-1].ahead
        out.print(f"{req} holds at every checked age up to {last} cycles ahead")
    elif result.fails_after == 0:
        out.print(f"{req} already fails now (cycle {result.now:g})")
    else:
        out.print(f"{req} stops holding after {result.fails_after} more cycles "
                  f"(cycle {result.now + result.fails_after:g}; located by bisection between "
                  "the checked ages, assuming one crossing between them)")


@click.command("recheck")
@click.argument("config", type=click.Path(path_type=Path))
@click.option("--cycles", "cycles_path", type=click.Path(path_type=Path), required=True,
              help="Newest capacity log (cycle,capacity_ah).")
@click.option("--discharge", "discharge_path", type=click.Path(path_type=Path), default=None,
              help="Newest discharge log (soc,voltage_v or time_s,voltage_v,current_a).")
@_model_option
@set_option
def recheck_command(config: Path, cycles_path: Path, discharge_path: Path | None,
                    model: str | None, overrides: tuple[str, ...]) -> None:
    """Refit the battery from the newest data and re-verify CONFIG; exit 1 on a regression."""
    from veribattery.phm.recheck import recheck

    with user_errors():
        result = recheck(config, cycles_path, discharge_path, overrides, model)
    print_warnings(result.after.warnings)
    _print_recheck(result)
    sys.exit(1 if result.regressions else 0)


def _print_recheck(result: Recheck) -> None:
    from rich.table import Table

    out.print("parameters moved by the refit ('-': not set that way before):", style="bold")
    for moved in result.moved:
        before = "-" if moved.before is None else _show(moved.before)
        out.print(f"  {moved.key}: {before} → {_show(moved.after)}", markup=False)
    if not result.moved:
        out.print("  none")
    table = Table("property", "before", "after", "change", show_edge=False)
    after = result.after.values
    for name, value in result.before.values.items():
        new = after.get(name)
        change = (f"{float(new) - float(value):+.6g}"
                  if isinstance(value, int | float) and isinstance(new, int | float) else "")
        table.add_row(str(name), format_value(value), format_value(new), change)
    out.print(table)
    _print_requirements(result)


def _print_requirements(result: Recheck) -> None:
    before = {str(o.requirement): o.holds for o in result.before.requirements}
    for outcome in result.after.requirements:
        name = str(outcome.requirement)
        was = "PASS" if before.get(name) else "FAIL"
        now = "[green]PASS[/]" if outcome.holds else "[bold red]FAIL[/]"
        out.print(f"{name}: before {was}, after {now}")
    if result.regressions:
        out.print(f"[bold red]no longer holds:[/] {', '.join(result.regressions)}")


def _short(value: object) -> str:
    """A value to 6 significant digits, for narrow tables."""
    return f"{value:.6g}" if isinstance(value, float) else format_value(value)


def _show(value: object) -> str:
    from fractions import Fraction

    from veribattery.config.exact import show

    return show(value) if isinstance(value, Fraction | str | tuple | list) else str(value)
