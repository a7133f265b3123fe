"""Figures of the PHM commands (matplotlib, imported on first use, no display needed)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from veribattery._files import staged
from veribattery.config.exact import show
from veribattery.phm.data import CycleLog
from veribattery.phm.forecast import Forecast
from veribattery.phm.refit import FadeParameters, LevelParameters

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["plot_fade", "plot_forecast", "plot_levels"]


def _figure(rows: int = 1) -> tuple[Figure, Any]:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 4.5 * rows), layout="constrained")
    return figure, figure.subplots(rows, 1, squeeze=False)[:, 0]


def _save(figure: Figure, path: Path) -> Path:
    """Write *figure* whole or not at all; its type follows *path*'s suffix."""
    with staged(path, suffix=path.suffix) as temporary:
        figure.savefig(temporary, dpi=120)
    return path


def plot_fade(log: CycleLog, params: FadeParameters, max_recharges: int,
              resolution_ah: float, path: Path) -> Path:
    """The data, every fit, and the model's step fade ``cap(rc)`` from the chosen cycle."""
    figure, (axes,) = _figure()
    axes.plot(log.cycle, log.capacity_ah, "o", ms=3, color="black", label="data")
    end = params.at_cycle + max_recharges
    cycles = np.linspace(float(log.cycle[0]), end, 400)
    for fit in params.report.fits:
        style = "-" if fit is params.fit else "--"
        axes.plot(cycles, fit.capacity(cycles), style, lw=1.5,
                  label=f"{fit.name} (AIC {fit.aic:.1f}, RMSE {fit.rmse:.3g} Ah)")
    rc = np.arange(max_recharges + 1)
    c_new = round(float(params.capacity_ah) / resolution_ah)
    cap = np.floor(c_new * (1 - float(params.fade_per_recharge) * rc) + 1e-9) * resolution_ah
    axes.step(params.at_cycle + rc, cap, where="post", color="tab:red", lw=1,
              label=f"model cap(rc): C_NEW {show(params.capacity_ah)} Ah, "
                    f"fade {show(params.fade_per_recharge)}/recharge")
    axes.axvline(params.at_cycle, color="grey", lw=0.8, ls=":")
    axes.set(xlabel="cycle (recharges)", ylabel="capacity (Ah)",
             title=f"Capacity fade: {params.fit.name} chosen by AIC")
    axes.grid(alpha=0.3)
    axes.legend(fontsize=8)
    return _save(figure, path)


def plot_levels(params: LevelParameters, path: Path) -> Path:
    """The discharge curve and the step approximation over it."""
    figure, (axes,) = _figure()
    steps = params.steps
    axes.plot(steps.soc, steps.voltage, color="black", lw=1.5, label="discharge curve")
    fine = np.linspace(float(steps.soc[0]), float(steps.soc[-1]), 2000)
    axes.plot(fine, steps.step(fine), color="tab:red", lw=2,
              label=f"BA3 steps (RMS error {steps.rms_v:.3g} V, max {steps.max_v:.3g} V)")
    for threshold in (steps.low, steps.high):
        axes.axvline(float(threshold), color="grey", ls=":", lw=1)
        axes.annotate(f"SOC {show(threshold)}", (float(threshold), float(steps.voltage.max())),
                      fontsize=8, ha="center", va="bottom")
    edges = (float(steps.soc[0]), float(steps.low), float(steps.high), float(steps.soc[-1]))
    for k, (name, volts) in enumerate(zip(("low", "medium", "high"), params.voltages_v,
                                          strict=True)):
        middle = (edges[k] + edges[k + 1]) / 2
        axes.annotate(f"{name}: {show(volts)} V", (middle, float(volts)), fontsize=8,
                      ha="center", va="bottom", xytext=(0, 3), textcoords="offset points")
    axes.invert_xaxis()
    axes.set(xlabel="state of charge (discharging →)", ylabel="voltage (V)",
             title="Voltage levels: step approximation minimising the squared error")
    axes.grid(alpha=0.3)
    axes.legend(fontsize=8, loc="lower left")
    return _save(figure, path)


def plot_forecast(result: Forecast, time_property: str | None, path: Path) -> Path:
    """The judged property and (optionally) mission time against cycles from now."""
    figure, rows = _figure(2 if time_property else 1)
    ahead = [p.ahead for p in result.points]
    req = result.requirement
    top = rows[0]
    top.plot(ahead, [_num(p.values[req.prop]) for p in result.points], "o-", ms=3)
    top.axhline(float(req.bound), color="tab:red", ls="--", lw=1, label=str(req))
    if result.fails_after is not None:
        top.axvline(result.fails_after, color="tab:red", ls=":", lw=1,
                    label=f"fails after {result.fails_after} more cycles")
    top.set(ylabel=req.prop)
    figure.suptitle(f"{req.prop} as the battery ages (from cycle {result.now:g})")
    top.legend(fontsize=8)
    if time_property:
        rows[1].plot(ahead, [_num(p.values[time_property]) for p in result.points], "o-", ms=3,
                     color="tab:green")
        rows[1].set(ylabel=time_property)
    rows[-1].set(xlabel="cycles from now")
    for axes in rows:
        axes.grid(alpha=0.3)
    every = ahead[:: max(1, len(ahead) // 6)]
    caps = {p.ahead: p.capacity_ah for p in result.points}
    capacity_axis = top.secondary_xaxis("top")
    capacity_axis.set_xticks(every, [f"{show(caps[a])}" for a in every], fontsize=8)
    capacity_axis.set_xlabel("new capacity used at that age (Ah)", fontsize=8)
    return _save(figure, path)


def _num(value: object) -> float:
    return float(value) if isinstance(value, int | float) else math.nan
