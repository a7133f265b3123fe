"""Figures from a :func:`~veribattery.sweep.run.run_sweep` frame (matplotlib, Agg: no display).

Figures are made with :class:`matplotlib.figure.Figure` on an Agg canvas rather than
through pyplot, so plotting needs no display and leaves the process's backend alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backend_bases import FigureCanvasBase
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from veribattery.errors import ConfigError

__all__ = ["check_plot_target", "plot_sweep"]

_NON_AXIS = {"point", "property", "value", "states", "transitions", "seconds", "requirement",
             "holds", "recharge_cap_probability", "error"}


def plot_sweep(frame: pd.DataFrame, x_key: str, property: str, path: str | Path) -> Path:
    """Plot *property* against the axis *x_key*: one line per combination of the other axes.

    The format follows the suffix of *path* (``.png``, ``.pdf``, ``.svg``).

    :raises ConfigError: when *x_key* is not an axis of *frame* or *property* is not in it.
    """
    path = Path(path)
    axes = [c for c in frame.columns if c not in _NON_AXIS]
    check_plot_target(path, x_key, axes)
    names = list(frame["property"].drop_duplicates())
    if property not in names:
        raise ConfigError(f"--plot-property: no property {property!r} (have: {', '.join(names)})")
    rows = frame[frame["property"] == property]
    figure = Figure(figsize=(7, 4.5), layout="constrained")
    FigureCanvasAgg(figure)
    _draw(figure.add_subplot(), rows, x_key, [k for k in axes if k != x_key], property)
    figure.savefig(path)
    return path


def check_plot_target(path: str | Path, x_key: str, axis_keys: Sequence[str]) -> None:
    """Check a plot's file type and x axis before any work is done.

    :raises ConfigError: on an unsupported suffix, or when *x_key* is not among *axis_keys*.
    """
    suffix = Path(path).suffix.lower().removeprefix(".")
    supported = FigureCanvasBase.get_supported_filetypes()
    if suffix not in supported:
        raise ConfigError(
            f"--plot {str(path)!r}: unsupported file type; use one of "
            + ", ".join(f".{s}" for s in sorted(supported))
        )
    if x_key not in axis_keys:
        raise ConfigError(f"--plot-x: {x_key!r} is not a varied key ({', '.join(axis_keys)})")


def _draw(ax: Axes, rows: pd.DataFrame, x_key: str, others: list[str], prop: str) -> None:
    if not others:
        ax.plot(rows[x_key], rows["value"].astype(float), marker="o")
    else:
        for values, group in rows.groupby(others, sort=False):
            label = ", ".join(f"{k}={v}" for k, v in zip(others, values, strict=True))
            ax.plot(group[x_key], group["value"].astype(float), marker="o", label=label)
        ax.legend(fontsize="small")
    ax.set_xlabel(x_key)
    ax.set_ylabel(prop)
    ax.set_title(f"{prop} vs {x_key}")
    ax.grid(True, alpha=0.3)
