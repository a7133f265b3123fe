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

__all__ = ["FadeParameters", "LevelParameters", "eq2_inputs", "fade_parameters",
           "level_parameters"]

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


def fade_parameters(log: CycleLog, cfg: MissionConfig, at_cycle: float | None = None,
                    model: str | None = None) -> FadeParameters:
    """Fit *log* and read the capacity and fade at *at_cycle* (default: the last cycle).

    :raises PhmDataError: when *at_cycle* is not a cycle number >= 0, or the chosen fit
        is not meaningful there (capacity not positive, or rising).
    """
    if at_cycle is not None and not (math.isfinite(at_cycle) and at_cycle >= 0):
        raise PhmDataError(f"at_cycle must be a cycle number >= 0, got {at_cycle:g}")
    report, fit = choose(log, model)
    cycle = float(log.cycle[-1]) if at_cycle is None else at_cycle
    capacity = float(fit.capacity(cycle))
    where = log.table.where(int(np.argmin(np.abs(log.cycle - cycle))), "capacity_ah")
    if capacity <= 0:
        raise PhmDataError(f"{where}: the {fit.name} fit gives capacity {capacity:.4g} Ah at "
                           f"cycle {cycle:g}; not a meaningful fit there")
    fade, interval = fit.relative_fade(cycle), fit.fade_interval(cycle)
    if fade < 0 <= interval[1]:
        fade = 0.0  # no measurable fade: the rise is within the fit's uncertainty
    if fade < 0:
        raise PhmDataError(f"{where}: the {fit.name} fit has the capacity rising at cycle "
                           f"{cycle:g} (fade {fade:.3g}/cycle); not a meaningful fade fit")
    grid = on_grid(capacity, cfg.battery.resolution_ah)
    units = grid / cfg.battery.resolution_ah
    if units > PRISM_INT_MAX // 2:  # else fade_value keeps no digit: a fade of 0, silently
        raise PhmDataError(
            f"{where}: the {fit.name} fit gives capacity {capacity:.4g} Ah at cycle {cycle:g}, "
            f"{float(units):.3g} units of battery.resolution_ah "
            f"({show(cfg.battery.resolution_ah)}); the model's 32-bit integers hold at most "
            f"{PRISM_INT_MAX // 2:,}: is the log in Ah?")
    value = fade_value(fade, cfg, grid)
    rc_max = cfg.battery.max_recharges
    if value == 0 < fade and units * fade * rc_max >= 1:
        raise PhmDataError(  # rounded to 0 for the integers, yet it costs whole units
            f"{where}: the fitted fade {fade:.3g}/cycle would round to 0: with "
            f"{float(units):.3g} units of battery.resolution_ah ({show(cfg.battery.resolution_ah)})"
            " the model's 32-bit integers hold no digit of it; raise battery.resolution_ah")
    if value * rc_max >= 1:
        raise PhmDataError(
            f"{where}: the fitted fade {show(value)}/recharge x battery.max_recharges {rc_max} "
            f">= 1, so the model's capacity would reach zero; set battery.max_recharges below "
            f"{math.ceil(1 / value)} (e.g. --set battery.max_recharges={math.ceil(1 / value) - 1})")
    return FadeParameters(report, fit, cycle, capacity, grid, fade, interval, value)


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
