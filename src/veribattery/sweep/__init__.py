"""Parameter sweeps: a grid over config keys, the mission checked at every point, figures.

This package is the only one importing pandas (and :mod:`veribattery.sweep.plot` the only
module importing matplotlib, loaded on first use of :func:`plot_sweep`)::

    axes = [parse_axis("battery.capacity_ah=10:13:0.5"), parse_axis("strategy.safe_t=0.25,0.3")]
    frame = run_sweep("mission.yaml", axes)      # one row per point x property
    frame = run_sweep("mission.yaml", axes, jobs=2, results="sweep.csv")  # durable, resumable

Modules: :mod:`~veribattery.sweep.grid` (axes and grids), :mod:`~veribattery.sweep.tasks`
(units of work; what a point gives back: :mod:`~veribattery.sweep.point_result`, and a
point in synthesis mode: :mod:`~veribattery.sweep.synthesis_point`),
:mod:`~veribattery.sweep.execute` (in-process, process pool, Dask),
:mod:`~veribattery.sweep.store` (durable RESULTS files), :mod:`~veribattery.sweep.fingerprint`
(which sweep a RESULTS file belongs to), :mod:`~veribattery.sweep.summary` (warnings),
:mod:`~veribattery.sweep.run` (the orchestration) and :mod:`~veribattery.sweep.plot`.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

# Imported now: the function grid shares its name with the module veribattery.sweep.grid,
# which would otherwise shadow it once imported.
from veribattery.sweep.grid import Axis, axes_from, grid, parse_axis, point_values

if TYPE_CHECKING:
    import pandas as pd

    from veribattery.sweep.execute import default_jobs
    from veribattery.sweep.run import (
        PointCallback,
        SweepProgress,
        any_requirement_fails,
        describe_point,
        records,
        run_sweep,
        wide,
    )
    from veribattery.sweep.summary import summary_line
    from veribattery.sweep.tasks import PointResult

# Exports are imported on first use: a worker process unpickling a task imports
# veribattery.sweep.tasks, and with it this package, and should not pay for pandas.
_EXPORTS = {
    "veribattery.sweep.execute": ("default_jobs",),
    "veribattery.sweep.run": ("PointCallback", "SweepProgress", "any_requirement_fails",
                              "describe_point", "records", "run_sweep", "wide"),
    "veribattery.sweep.summary": ("summary_line",),
    "veribattery.sweep.tasks": ("PointResult",),
}
_HOME = {name: module for module, names in _EXPORTS.items() for name in names}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'veribattery.sweep' has no attribute {name!r}")
    return getattr(importlib.import_module(_HOME[name]), name)


__all__ = [
    "Axis",
    "PointCallback",
    "PointResult",
    "SweepProgress",
    "any_requirement_fails",
    "axes_from",
    "default_jobs",
    "describe_point",
    "grid",
    "parse_axis",
    "plot_sweep",
    "point_values",
    "records",
    "run_sweep",
    "summary_line",
    "wide",
]


def plot_sweep(frame: pd.DataFrame, x_key: str | None, property: str, path: str | Path, *,
               properties: Mapping[str, str] | None = None) -> Path:
    """Plot *property* against *x_key* (None: the first numeric varied key); see
    :func:`veribattery.sweep.plot.plot_sweep`."""
    from veribattery.sweep.plot import plot_sweep as plot

    return plot(frame, x_key, property, path, properties=properties)
