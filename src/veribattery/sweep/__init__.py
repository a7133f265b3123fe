"""Parameter sweeps: a grid over config keys, the mission checked at every point, figures.

This package is the only one importing pandas (and :mod:`veribattery.sweep.plot` the only
module importing matplotlib, loaded on first use of :func:`plot_sweep`)::

    axes = [parse_axis("battery.capacity_ah=10:13:0.5"), parse_axis("strategy.safe_t=0.25,0.3")]
    frame = run_sweep("mission.yaml", axes)      # one row per point x property
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from veribattery.sweep.grid import Axis, grid, parse_axis, point_overrides
from veribattery.sweep.run import SweepProgress, any_requirement_fails, records, run_sweep, wide

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "Axis",
    "SweepProgress",
    "any_requirement_fails",
    "grid",
    "parse_axis",
    "plot_sweep",
    "point_overrides",
    "records",
    "run_sweep",
    "wide",
]


def plot_sweep(frame: pd.DataFrame, x_key: str, property: str, path: str | Path) -> Path:
    """Plot *property* against *x_key*; see :func:`veribattery.sweep.plot.plot_sweep`."""
    from veribattery.sweep.plot import plot_sweep as plot

    return plot(frame, x_key, property, path)
