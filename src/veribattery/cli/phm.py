"""The battery prognostics commands: ``phm fade|levels|simulate|forecast`` and ``recheck``."""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

from veribattery.cli import phm_output as said
from veribattery.cli.files import FIGURE_SUFFIXES, PathParam, check_output_dir, check_output_file
from veribattery.cli.output import (
    LiveStatus,
    build_progress,
    print_warnings,
    set_option,
    user_errors,
)
from veribattery.cli.phm_output import (
    files_written,
    print_fade,
    print_files,
    print_fits,
    print_forecast,
    print_forecast_csv,
    print_fragment,
    print_json,
    print_levels,
    print_recheck,
)
from veribattery.cli.progress import PlainProgress
from veribattery.errors import OptionError

if TYPE_CHECKING:
    from fractions import Fraction

    from veribattery.config import MissionConfig, Requirement
    from veribattery.phm.data import CycleLog, DischargeCurve
    from veribattery.phm.forecast import Forecast
    from veribattery.phm.levels import StepFit
    from veribattery.phm.refit import FadeParameters, LevelParameters

F = TypeVar("F", bound=Callable[..., Any])

MODELS = click.Choice(["linear", "exponential", "knee"])


def _plot_option(function: F) -> F:
    function = click.option("--force", is_flag=True,
                            help="Let --plot overwrite an existing file.")(function)
    return click.option("--plot", "plot_path", type=PathParam(path_type=Path), metavar="FILE",
                        help="Also write a figure here; its type follows the suffix "
                             "(.png, .pdf, .svg, ...).")(function)


def _format_option(*formats: str, text: str = "Output format (json: one object).",
                   ) -> Callable[[F], F]:
    return click.option("--format", "output_format", type=click.Choice(formats),
                        default="table", show_default=True, help=text)


def _model_option(function: F) -> F:
    return click.option("--model", type=MODELS, default=None,
                        help="Use this fade model instead of the AIC choice.")(function)


def _check_plot(path: Path | None, force: bool) -> None:
    check_output_file(path, "--plot", force=force, suffixes=FIGURE_SUFFIXES)


def _typed(text: str) -> str:
    """An option's value as the user typed it (an empty one shown as ``''``)."""
    return text if text else "''"


def _number(option: str, text: str | None, rule: str,
            accept: Callable[[float], bool]) -> float | None:
    """*text* as a finite float that *accept* takes (None stays None), else an
    :class:`OptionError` saying *rule*."""
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or not accept(value):
        raise OptionError(f"{option} {_typed(text)}: {rule}")
    return value


def _at_cycle(text: str | None) -> float | None:
    return _number("--at-cycle", text, "must be a cycle number >= 0, e.g. 300 (leave it out "
                   "for the last logged cycle)", lambda value: value >= 0)


def _capacity(text: str | None) -> float | None:
    return _number("--capacity-ah", text, "must be a positive number of Ah (Q_max, the full "
                   "battery's charge), e.g. 5.0; leave it out to use the charge the log "
                   "delivers", lambda value: value > 0)


def _fade_at(log: CycleLog, cfg: MissionConfig, cycle: float | None, model: str | None,
             typed: str | None, source: Path | None) -> FadeParameters:
    """:func:`fade_parameters`, a cycle too far ahead blamed on --at-cycle, and a clash
    with battery.max_recharges on that key of *source* (the config read, None: the
    paper's), to be set in the file: fade has no --set."""
    from veribattery.phm.refit import BeyondDataError, RechargeCapError, fade_parameters

    try:
        return fade_parameters(log, cfg, cycle, model)
    except BeyondDataError as exc:
        raise said.too_far("--at-cycle", typed or "", exc, exc.last + exc.ahead) from None
    except RechargeCapError as exc:
        raise said.recharge_cap_error(cfg, exc, said.file_remedy(exc, source)) from None


def _base_config(config: Path | None, write: Path | None) -> MissionConfig:
    """The config read for the fit: --write's (the file merged into), --config's, or the
    paper's."""
    from veribattery.config import load_config

    if config is not None and write is not None:
        raise OptionError(f"--config {config} --write {write}: give one of them; --write "
                          "reads the config it merges into, so it is also the config used")
    said.check_input_file(config, "--config", said.CONFIG_REMEDY)
    said.check_input_file(write, "--write", said.WRITE_REMEDY)
    check_output_file(write, "--write", force=True)
    said.check_links(write)
    source = write if write is not None else config
    return load_config(source) if source is not None else load_config("")


def _merged(write: Path | None, values: dict[str, object], command: str,
            data: str) -> str | None:
    """The --write config with *values* merged, validated (None without --write); a
    replaced value's comment about the old one says they came from *command* on *data*."""
    if write is None:
        return None
    from veribattery.config import load_config
    from veribattery.phm.merge import merge_text

    note = f"fitted by veribattery phm {command} from {Path(data).name}"
    merged = merge_text(write.read_text(encoding="utf-8"), values, str(write), note)
    load_config(merged + "\n")  # the merged config must validate before it replaces the file
    return merged


def _write(write: Path | None, merged: str | None) -> None:
    if write is not None and merged is not None:
        from veribattery.phm.merge import write_atomic

        write_atomic(write, merged)


@click.group("phm", short_help="Battery parameters from data or physics; forecasts.")
def phm_group() -> None:
    """Battery prognostics: model parameters from cycling data, discharge curves, physics."""


@phm_group.command("fade", short_help="Fit capacity fade per cycle from a capacity log.")
@click.argument("cycles", type=PathParam())
@click.option("--at-cycle", metavar="CYCLE", default=None,
              help="Cycle the battery is at, >= 0 (default: the last logged cycle).")
@click.option("--config", type=PathParam(path_type=Path),
              help="Config for resolution_ah and max_recharges (default: the paper's).")
@click.option("--write", type=PathParam(path_type=Path),
              help="Merge battery.capacity_ah and fade_per_recharge into this config "
                   "(also the config read; not with --config).")
@_model_option
@_plot_option
@_format_option("table", "json")
def fade_command(cycles: str, at_cycle: str | None, config: Path | None, write: Path | None,
                 model: str | None, plot_path: Path | None, force: bool,
                 output_format: str) -> None:
    """Fit capacity fade per cycle in CYCLES.csv (cycle,capacity_ah)."""
    from veribattery.phm.data import read_cycles

    with user_errors():
        _check_plot(plot_path, force)
        cycle = _at_cycle(at_cycle)
        cfg = _base_config(config, write)
        log = read_cycles(cycles)
        params = _fade_at(log, cfg, cycle, model, at_cycle, write or config)
        merged = _merged(write, params.fragment.values, "fade", cycles)
        if plot_path is not None:
            from veribattery.phm.plot import plot_fade

            plot_fade(log, params, cfg.battery.max_recharges,
                      float(cfg.battery.resolution_ah), plot_path)
        _write(write, merged)
    if output_format == "json":
        from veribattery.phm.documents import fade_document

        print_json({"cycles": cycles, **fade_document(params),
                     **files_written(params.fragment, plot_path, write)})
    else:
        print_fits(params.report)
        print_fade(params)
        print_fragment(params.fragment)
    print_files(plot_path, write)


@phm_group.command("levels", short_help="Voltage levels, SOC thresholds, consumption.")
@click.argument("discharge", type=PathParam())
@click.option("--capacity-ah", metavar="AH", default=None,
              help="Q_max for Coulomb counting, > 0 (default: the charge the log delivers).")
@click.option("--soc-step", type=str, default="0.01", show_default=True,
              help="SOC grid on which thresholds are chosen (exact decimal in (0, 0.1]).")
@click.option("--config", type=PathParam(path_type=Path),
              help="Config for Eq. 2's energy, times and resolution_ah (default: the paper's).")
@click.option("--write", type=PathParam(path_type=Path),
              help="Merge voltage_thresholds and an Eq. 2 consumption into this config "
                   "(also the config read; not with --config).")
@_plot_option
@_format_option("table", "json")
def levels_command(discharge: str, capacity_ah: str | None, soc_step: str,
                   config: Path | None, write: Path | None, plot_path: Path | None,
                   force: bool, output_format: str) -> None:
    """Derive voltage levels, SOC thresholds and consumption from a discharge curve.

    The thresholds are the paper's assumption BA3: the voltage level is high above
    one SOC, low below another and medium in between.
    """
    from veribattery.phm.data import read_discharge

    with user_errors():
        _check_plot(plot_path, force)
        capacity, step = _capacity(capacity_ah), _soc_step(soc_step)
        cfg = _base_config(config, write)
        curve = read_discharge(discharge, capacity)
        params = _levels(curve, cfg, step, capacity_ah, soc_step)
        paper = _config_steps(curve, cfg, step)
        merged = _merged(write, params.fragment.values, "levels", discharge)
        if plot_path is not None:
            from veribattery.phm.plot import plot_levels

            plot_levels(params, plot_path)
        _write(write, merged)
    if output_format == "json":
        from veribattery.phm.documents import levels_document

        print_json({"discharge": discharge, **levels_document(params, paper),
                     **files_written(params.fragment, plot_path, write)})
    else:
        print_levels(params, paper)
        print_fragment(params.fragment)
    print_files(plot_path, write)


def _levels(curve: DischargeCurve, cfg: MissionConfig, step: Fraction,
            capacity_ah: str | None, soc_step: str) -> LevelParameters:
    """:func:`level_parameters`, a SOC grid that does not suit the curve blamed on the
    option that set it: --soc-step (too fine), --capacity-ah (a SOC range too narrow)."""
    from veribattery.phm.levels import SocGridError
    from veribattery.phm.refit import level_parameters

    try:
        return level_parameters(curve, cfg, step)
    except SocGridError as exc:
        blamed = said.soc_grid_error(exc, curve.charge_ah, capacity_ah, soc_step)
        if blamed is None:
            raise  # the log is too short for the grid
        raise blamed from None


def _config_steps(curve: DischargeCurve, cfg: MissionConfig, step: Fraction) -> StepFit | None:
    """The config's own thresholds on *curve*, for comparison (None when they do not fit)."""
    from veribattery.phm.data import PhmDataError
    from veribattery.phm.levels import fixed_steps

    thresholds = cfg.battery.voltage_thresholds
    try:
        return fixed_steps(curve, thresholds.low, thresholds.high, step)
    except PhmDataError:  # the comparison is informative only
        return None


def _soc_step(text: str) -> Fraction:
    from fractions import Fraction

    rule = "must be a decimal in (0, 0.1], e.g. 0.01"
    try:
        step = Fraction(text)
    except (ValueError, ZeroDivisionError):
        raise OptionError(f"--soc-step {_typed(text)}: {rule}") from None
    if not 0 < step <= Fraction(1, 10):
        raise OptionError(f"--soc-step {text}: {rule}")
    return step


@phm_group.command("simulate", short_help="PyBaMM discharge (and ageing) CSVs.")
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
              default="reaction limited", show_default=True, metavar="MODEL",
              help="SEI growth submodel of the ageing experiment: 'reaction limited', "
              "'solvent-diffusion limited', 'ec reaction limited' or "
              "'interstitial-diffusion limited'.")
@click.option("--period-s", type=click.FloatRange(min=1), default=30.0, show_default=True,
              help="Output time step of the discharge, s.")
@click.option("-o", "--output", "out_dir", type=PathParam(path_type=Path), default=Path("."),
              show_default=True, help="Directory for discharge.csv (and cycles.csv).")
@click.option("--force", is_flag=True, help="Overwrite existing CSVs.")
def simulate_command(parameter_set: str, power_w: float, cells_series: int,
                     cells_parallel: int, cycles: int | None, sei: str, period_s: float,
                     out_dir: Path,
                     force: bool) -> None:
    """Physics when there is no data: PyBaMM discharge (and ageing) CSVs."""
    from veribattery.phm.simulate import CYCLES_FILE, DISCHARGE_FILE, Pack, simulate, write_csvs

    with user_errors():
        names = [DISCHARGE_FILE, *([CYCLES_FILE] if cycles else [])]
        check_output_dir(out_dir, "-o", force=force, names=names)
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


@phm_group.command("forecast",
                   short_help="When a requirement stops holding; exit 1 within the horizon.")
@click.argument("config", type=PathParam(path_type=Path))
@click.option("--cycles", "cycles_path", type=PathParam(), required=True,
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
@_format_option("table", "json", "csv",
                text="Output format (json: one object; csv: the table, full precision).")
def forecast_command(config: Path, cycles_path: str, horizon: int, step: int | None,
                     requirement: str, time_property: str, model: str | None,
                     overrides: tuple[str, ...], plot_path: Path | None, force: bool,
                     output_format: str) -> None:
    """P(success) and mission time as the battery ages; when does REQUIRE stop holding?

    Exits 1 when it fails at an age checked (now or within --horizon), 0 when it holds
    at every one.
    """
    from veribattery.config import load_config
    from veribattery.phm.data import read_cycles

    with user_errors():
        _check_plot(plot_path, force)
        req = _requirement(requirement)
        said.check_input_file(cycles_path, "--cycles", said.CYCLES_REMEDY)
        cfg = load_config(config, overrides)
        _check_property(cfg, config, f"--require {requirement}", req.prop)
        _check_bound(req, cfg.properties, f"--require {requirement}")
        if time_property:
            _check_property(cfg, config, f"--time-property {time_property}", time_property)
        log = read_cycles(cycles_path)
        result = _forecast(config, cfg, log, req, (horizon, step or max(1, horizon // 10)),
                           overrides, model)
        if plot_path is not None:
            from veribattery.phm.plot import plot_forecast

            plot_forecast(result, time_property or None, plot_path)
    shown = _shown_properties(result, time_property)
    if output_format == "json":
        from veribattery.phm.documents import forecast_document

        print_json({"config": str(config), **forecast_document(result),
                     "time_property": time_property or None,
                     "figure": None if plot_path is None else str(plot_path)})
    elif output_format == "csv":
        print_forecast_csv(result, shown)
    else:
        print_forecast(result, shown)
    print_files(plot_path)
    # As a sweep over ages: a requirement failing at any age checked (now or within the
    # horizon) fails the run, so a nightly job can gate on "holds for the next N cycles".
    sys.exit(1 if result.fails_after is not None else 0)


def _forecast(config: Path, cfg: MissionConfig, log: CycleLog, req: Requirement,
              ages: tuple[int, int], overrides: tuple[str, ...], model: str | None
              ) -> Forecast:
    """:func:`forecast` over (horizon, step), showing the age checked on stderr; an age
    too far ahead blamed on --horizon, a clash now on *cfg*'s battery.max_recharges."""
    from veribattery.phm.forecast import forecast
    from veribattery.phm.refit import BeyondDataError, RechargeCapError

    horizon, step = ages
    try:
        with build_progress(plain=True) as progress:
            return forecast(config, log, req, horizon, step, overrides, model,
                            None if progress is None else _age_stage(progress))
    except BeyondDataError as exc:
        raise said.too_far("--horizon", str(horizon), exc, exc.ahead or None) from None
    except RechargeCapError as exc:
        raise said.recharge_cap_error(cfg, exc, said.set_remedy(exc)) from None


def _age_stage(progress: LiveStatus | PlainProgress) -> Callable[[int, int, float], None]:
    """The forecast's progress: each age checked is a stage (a spinner's text, or a line)."""

    def tell(number: int, grid: int, cycle: float) -> None:
        which = f"age {number} of {grid}" if grid else f"age {number}, bisecting"
        progress.step(f"checking the mission at cycle {cycle:g} ({which})")

    return tell


def _requirement(text: str) -> Requirement:
    from veribattery.config import parse_requirement

    try:
        return parse_requirement(text)
    except ValueError as exc:
        raise OptionError(f"--require: {exc}") from None


def _check_property(cfg: MissionConfig, config: Path, where: str, name: str) -> None:
    """*name* must be one of the properties *cfg* checks."""
    if name not in cfg.properties:
        raise OptionError(f"{where}: {config} has no property '{name}'; its properties are "
                          f"{', '.join(cfg.properties)}")


def _check_bound(req: Requirement, properties: Mapping[str, str], where: str) -> None:
    """A probability's bound must lie in [0, 1]: else the requirement says nothing."""
    from veribattery.config import requirement_problem

    problem = requirement_problem(req, properties[req.prop], properties)
    if problem is not None:
        raise OptionError(f"{where}: {problem}")


def _shown_properties(result: Forecast, time_property: str) -> list[str]:
    """The forecast table's property columns: the requirement's, then the time property."""
    prop = result.requirement.prop
    return [prop, *([time_property] if time_property and time_property != prop else [])]


@click.command("recheck", short_help="Refit from new data and re-verify; exit 1 on a regression.")
@click.argument("config", type=PathParam(path_type=Path))
@click.option("--cycles", "cycles_path", type=PathParam(), required=True,
              help="Newest capacity log (cycle,capacity_ah).")
@click.option("--discharge", "discharge_path", type=PathParam(), default=None,
              help="Newest discharge log (soc,voltage_v or time_s,voltage_v,current_a).")
@_model_option
@set_option
@_format_option("table", "json")
def recheck_command(config: Path, cycles_path: str, discharge_path: str | None,
                    model: str | None, overrides: tuple[str, ...], output_format: str) -> None:
    """Refit the battery from the newest data and re-verify CONFIG; exit 1 on a regression."""
    from veribattery.phm.recheck import recheck
    from veribattery.phm.refit import RechargeCapError

    with user_errors():
        said.check_input_file(cycles_path, "--cycles", said.CYCLES_REMEDY)
        said.check_input_file(discharge_path, "--discharge", said.DISCHARGE_REMEDY)
        try:
            result = recheck(config, cycles_path, discharge_path, overrides, model)
        except RechargeCapError as exc:
            from veribattery.config import load_config

            cfg = load_config(config, overrides)  # loaded before: it loads
            raise said.recharge_cap_error(cfg, exc, said.set_remedy(exc)) from None
    from veribattery.phm.documents import recheck_document

    print_warnings(result.after.warnings)
    document = recheck_document(result)
    if output_format == "json":
        print_json({"config": str(config), **document})
    else:
        print_recheck(result, document)
    sys.exit(1 if result.regressions else 0)

