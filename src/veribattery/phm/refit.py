"""From data to config values: the battery keys a fade log and a discharge curve give.

:func:`fade_parameters` turns a capacity log into ``battery.capacity_ah`` (on the
config's ``resolution_ah`` grid) and ``battery.fade_per_recharge``;
:func:`level_parameters` turns a discharge curve into ``battery.voltage_thresholds``
and an Eq. 2 ``battery.consumption``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from veribattery.config import MissionConfig
from veribattery.config.exact import show
from veribattery.config.params import PRISM_INT_MAX
from veribattery.config.schema import ConsumptionEq2
from veribattery.phm.data import CycleLog, DischargeCurve, PhmDataError
from veribattery.phm.fade import FadeFit, FadeReport, choose
from veribattery.phm.fragment import Fragment, decimal, fade_value, on_grid
from veribattery.phm.levels import LEVELS, WINDS, Eq2Inputs, StepFit, eq2_table, fit_steps

__all__ = ["BeyondDataError", "FadeParameters", "LevelParameters", "RechargeCapError",
           "eq2_inputs", "fade_parameters", "level_parameters", "parameters_at"]

#: Decimal places of a fitted voltage level in the config (10 mV).
VOLT_PLACES = 2


@dataclass(frozen=True, slots=True)
class FadeParameters:
    """The fade fit evaluated at one cycle, and the config values it gives.

    :ivar report: every fit and the AIC ranking.
    :ivar fit: the fit used.
    :ivar at_cycle: the cycle the battery is at (``C_NEW`` is its capacity there).
    :ivar capacity_fit_ah: fitted capacity at *at_cycle*.
    :ivar capacity_ah: the same on the ``resolution_ah`` grid.
    :ivar fade: fitted relative loss per cycle at *at_cycle* (0 when negative but not
        significantly so).
    :ivar fade_ci: its 95% confidence interval.
    :ivar fade_per_recharge: the exact decimal written to the config.
    """

    report: FadeReport
    fit: FadeFit
    at_cycle: float
    capacity_fit_ah: float
    capacity_ah: Fraction
    fade: float
    fade_ci: tuple[float, float]
    fade_per_recharge: Fraction

    @property
    def fragment(self) -> Fragment:
        """``battery.capacity_ah`` and ``battery.fade_per_recharge``."""
        return Fragment({"battery.capacity_ah": self.capacity_ah,
                         "battery.fade_per_recharge": self.fade_per_recharge})


class BeyondDataError(PhmDataError):
    """The fit gives no usable values at a cycle past the log, though it does at the log's
    last cycle: the cycle asked for lies too far ahead (an option's fault, not the data's).

    :ivar cycle: the cycle asked for.
    :ivar last: the log's last cycle.
    :ivar ahead: the most whole cycles past *last* at which the fit is still usable.
    :ivar reason: what goes wrong at *cycle*.
    """

    def __init__(self, cycle: float, last: float, ahead: int, reason: str) -> None:
        super().__init__(f"cycle {cycle:g} is too far beyond the log's last cycle {last:g}: "
                         f"{reason}; the fit is usable up to cycle {last + ahead:.15g}")
        self.cycle, self.last, self.ahead, self.reason = cycle, last, ahead, reason


class RechargeCapError(PhmDataError):
    """The fitted fade and the config's ``battery.max_recharges`` clash: after that many
    recharges the model's capacity would reach zero. The config key is at fault (or the
    fit), not a cell of the log; each command says how to set the key its own way.

    :ivar fade: the fade per recharge, as it would be written to the config.
    :ivar max_recharges: the config's ``battery.max_recharges``.
    :ivar largest: the largest ``battery.max_recharges`` that works with *fade*.
    """

    def __init__(self, fade: Fraction, max_recharges: int) -> None:
        self.fade, self.max_recharges = fade, max_recharges
        self.largest = math.ceil(1 / fade) - 1
        super().__init__(f"battery.max_recharges: {self.problem}; it must be at most "
                         f"{self.largest}")

    @property
    def problem(self) -> str:
        """What is wrong, without a remedy."""
        return (f"{self.max_recharges} recharges x the fitted fade {show(self.fade)}/recharge "
                ">= 1, so the model's capacity would reach zero")


def fade_parameters(log: CycleLog, cfg: MissionConfig, at_cycle: float | None = None,
                    model: str | None = None) -> FadeParameters:
    """Fit *log* and read the capacity and fade at *at_cycle* (default: the last cycle).

    :raises BeyondDataError: when *at_cycle* lies past the log, further than the fit
        gives usable values.
    :raises PhmDataError: when *at_cycle* is not a cycle number >= 0, or the chosen fit
        is not meaningful there (capacity not positive, or rising).
    """
    if at_cycle is not None and not (math.isfinite(at_cycle) and at_cycle >= 0):
        raise PhmDataError(f"at_cycle must be a cycle number >= 0, got {at_cycle:g}")
    report, fit = choose(log, model)
    cycle = float(log.cycle[-1]) if at_cycle is None else at_cycle
    return parameters_at(log, report, fit, cfg, cycle)


def parameters_at(log: CycleLog, report: FadeReport, fit: FadeFit, cfg: MissionConfig,
                  cycle: float) -> FadeParameters:
    """The config values *fit* (one of *report*'s, fitted to *log*) gives at *cycle*.

    :raises BeyondDataError: when *cycle* lies past the log, further than *fit* gives
        usable values.
    :raises RechargeCapError: when the fade at *cycle* x ``battery.max_recharges`` >= 1.
    :raises PhmDataError: when *fit* gives no usable values at *cycle* otherwise, located
        at the logged row nearest to it.
    """
    try:
        return _evaluate(report, fit, cfg, cycle)
    except PhmDataError as exc:
        last = float(log.cycle[-1])
        ahead = _usable_ahead(report, fit, cfg, last, cycle) if cycle > last else None
        if ahead is not None:
            raise BeyondDataError(cycle, last, ahead, str(exc)) from None
        if isinstance(exc, RechargeCapError):
            raise  # the config's key, not the log's row, is what to change
        where = log.table.where(int(np.argmin(np.abs(log.cycle - cycle))), "capacity_ah")
        raise PhmDataError(f"{where}: {exc}") from None


def _usable_ahead(report: FadeReport, fit: FadeFit, cfg: MissionConfig, last: float,
                  cycle: float) -> int | None:
    """The most whole cycles past *last* (short of *cycle*, where *fit* fails) at which
    *fit* is usable; None when it is not usable at *last* either (the data's fault).

    Bisection: a fading battery's fit gets worse the further out it is read.
    """
    if not _usable(report, fit, cfg, last):
        return None
    good, bad = 0, math.ceil(cycle - last)
    while bad - good > 1:
        middle = (good + bad) // 2
        if _usable(report, fit, cfg, last + middle):
            good = middle
        else:
            bad = middle
    return good


def _usable(report: FadeReport, fit: FadeFit, cfg: MissionConfig, cycle: float) -> bool:
    try:
        _evaluate(report, fit, cfg, cycle)
    except PhmDataError:
        return False
    return True


def _evaluate(report: FadeReport, fit: FadeFit, cfg: MissionConfig,
              cycle: float) -> FadeParameters:
    """:func:`parameters_at` without the location: a PhmDataError says only what is wrong."""
    capacity, fade, interval = _read_fit(fit, cycle)
    grid = on_grid(capacity, cfg.battery.resolution_ah)
    _check_units(fit, cfg, cycle, capacity, grid)
    value = fade_value(fade, cfg, grid)
    _check_fade(cfg, fade, value, grid)
    return FadeParameters(report, fit, cycle, capacity, grid, fade, interval, value)


def _read_fit(fit: FadeFit, cycle: float) -> tuple[float, float, tuple[float, float]]:
    """Capacity, fade and the fade's interval at *cycle*, checked to be meaningful."""
    # Read far out, a fit can overflow: inf or nan come back and are refused here, rather
    # than numpy's warnings going to the terminal.
    with np.errstate(all="ignore"):
        capacity = float(fit.capacity(cycle))
        if not (capacity > 0 and math.isfinite(capacity)):
            raise PhmDataError(f"the {fit.name} fit gives capacity {capacity:.4g} Ah at cycle "
                               f"{cycle:g}; not a meaningful fit there")
        fade, interval = fit.relative_fade(cycle), fit.fade_interval(cycle)
    if not all(map(math.isfinite, (fade, *interval))):
        raise PhmDataError(f"the {fit.name} fit's fade at cycle {cycle:g} is beyond floating "
                           "point (the fit overflows there); not a meaningful fit there")
    if fade < 0 <= interval[1]:
        fade = 0.0  # no measurable fade: the rise is within the fit's uncertainty
    if fade < 0:
        raise PhmDataError(f"the {fit.name} fit has the capacity rising at cycle {cycle:g} "
                           f"(fade {fade:.3g}/cycle); not a meaningful fade fit")
    return capacity, fade, interval


def _check_units(fit: FadeFit, cfg: MissionConfig, cycle: float, capacity: float,
                 grid: Fraction) -> None:
    """The capacity must fit the model's integers, else fade_value keeps no digit of the
    fade: a fade of 0, silently."""
    resolution = cfg.battery.resolution_ah
    units = grid / resolution
    if units > PRISM_INT_MAX // 2:
        raise PhmDataError(
            f"the {fit.name} fit gives capacity {capacity:.4g} Ah at cycle {cycle:g}, "
            f"{float(units):.3g} units of battery.resolution_ah ({show(resolution)}); the "
            f"model's 32-bit integers hold at most {PRISM_INT_MAX // 2:,}: is the log in Ah?")


def _check_fade(cfg: MissionConfig, fade: float, value: Fraction, grid: Fraction) -> None:
    resolution, rc_max = cfg.battery.resolution_ah, cfg.battery.max_recharges
    units = grid / resolution
    if value == 0 < fade and units * fade * rc_max >= 1:
        raise PhmDataError(  # rounded to 0 for the integers, yet it costs whole units
            f"the fitted fade {fade:.3g}/cycle would round to 0: with {float(units):.3g} "
            f"units of battery.resolution_ah ({show(resolution)}) the model's 32-bit "
            "integers hold no digit of it; raise battery.resolution_ah")
    if value * rc_max >= 1:
        raise RechargeCapError(value, rc_max)


@dataclass(frozen=True, slots=True)
class LevelParameters:
    """The step approximation and the config values it gives.

    :ivar steps: thresholds, levels and error.
    :ivar voltages_v: the three levels as exact decimals (10 mV).
    :ivar inputs: Eq. 2's other inputs (from the config, or the paper's).
    :ivar table: Eq. 2's consumption in units, action → ``[wind][level]``.
    :ivar resolution: the config's ``resolution_ah``.
    """

    steps: StepFit
    voltages_v: tuple[Fraction, Fraction, Fraction]
    inputs: Eq2Inputs
    table: dict[str, tuple[tuple[int, int, int], ...]]
    resolution: Fraction

    @property
    def fragment(self) -> Fragment:
        """``battery.voltage_thresholds`` and an Eq. 2 ``battery.consumption``."""
        consumption = {
            "energy_wh": self.inputs.energy_wh,
            "voltages_v": dict(zip(LEVELS, self.voltages_v, strict=True)),
            "flight_time_h": dict(zip(WINDS, self.inputs.flight_time_h, strict=True)),
            "action_time_h": dict(self.inputs.action_time_h),
        }
        return Fragment({"battery.voltage_thresholds.high": self.steps.high,
                         "battery.voltage_thresholds.low": self.steps.low,
                         "battery.consumption": consumption})


def eq2_inputs(cfg: MissionConfig) -> Eq2Inputs:
    """Eq. 2's energy and times from *cfg* when it uses Eq. 2, else the paper's."""
    source = cfg.battery.consumption
    eq2 = source if isinstance(source, ConsumptionEq2) else ConsumptionEq2()
    times = eq2.action_time_h
    return Eq2Inputs(eq2.energy_wh, (eq2.flight_time_h.low_wind, eq2.flight_time_h.high_wind),
                     {"takeoff_land": times.takeoff_land, "cell": times.cell,
                      "inspection": times.inspection})


def level_parameters(curve: DischargeCurve, cfg: MissionConfig,
                     step: Fraction = Fraction(1, 100)) -> LevelParameters:
    """Fit the steps on *curve* and compute Eq. 2's table with the fitted voltages.

    :raises PhmDataError: when a fitted level is not positive.
    """
    steps = fit_steps(curve, step)
    voltages = tuple(decimal(v, VOLT_PLACES) for v in steps.voltages)
    if min(voltages) <= 0:
        raise PhmDataError(f"{curve.source}: column 'voltage_v': a fitted voltage level is "
                           f"{min(voltages)} V; Eq. 2 needs positive voltages")
    inputs = eq2_inputs(cfg)
    resolution = cfg.battery.resolution_ah
    triple = (voltages[0], voltages[1], voltages[2])
    return LevelParameters(steps, triple, inputs, eq2_table(inputs, triple, resolution),
                           resolution)
