"""Figures from a :func:`~veribattery.sweep.run.run_sweep` frame (matplotlib, Agg: no display).

A sweep figure is drawn like the seed paper's Fig. 6: a numeric varied key on x (the
first whose values are all numbers, unless one is chosen), one line with markers per
combination of the other varied keys (a legend titled with those keys), readable labels
with units (:mod:`veribattery.sweep.labels`), and a probability on a y axis from 0 to 1.
A non-numeric key chosen for x is drawn categorically, at evenly spaced ticks. Failed
points are left out (and counted above the plot), never drawn as zeros.

Figures are made with :class:`matplotlib.figure.Figure` on an Agg canvas rather than
through pyplot, so plotting needs no display and leaves the process's backend alone.
"""

from __future__ import annotations

import itertools
import math
import numbers
import os
import shutil
from collections.abc import Collection, Hashable, Mapping, Sequence
from pathlib import Path

import pandas as pd
from matplotlib import rcParams
from matplotlib.axes import Axes
from matplotlib.backend_bases import FigureCanvasBase
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from veribattery._files import staged
from veribattery.errors import ConfigError, VeribatteryError
from veribattery.lang import ProbOp, parse_property
from veribattery.lang.nodes import SteadyOp
from veribattery.sweep.labels import key_label, property_label
from veribattery.sweep.run import FIXED_COLUMNS

__all__ = ["axis_keys", "check_plot_target", "plot_suffixes", "plot_sweep", "sweep_figure"]

_NON_AXIS = frozenset({"point", *FIXED_COLUMNS})
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "*")
_STYLES = ("-", "--", "-.", ":")
#: Legend entries per column, and at most (the last saying how many more lines).
_LEGEND_ROWS = 20
_LEGEND_MOST = 40
#: The most x values that each get a tick.
_GRID_TICKS = 12


def plot_sweep(frame: pd.DataFrame, x_key: str | None, property: str, path: str | Path, *,
               properties: Mapping[str, str] | None = None) -> Path:
    """Draw :func:`sweep_figure` and write it to *path* atomically (mode from the umask).

    The format follows the suffix of *path* (``.png``, ``.pdf``, ``.svg``, …).

    :param x_key: the varied key on x; None: the first numeric one (else the first).
    :param property: the property drawn.
    :param properties: the config's properties (name → PRISM formula): decide which
        properties are probabilities (y from 0 to 1) and check *property*.
    :raises ConfigError: as :func:`check_plot_target` and :func:`sweep_figure`, before
        anything is written.
    """
    path = Path(path)
    check_plot_target(path, x_key, axis_keys(frame))
    figure = sweep_figure(frame, x_key, property, properties=properties)
    with staged(path, suffix=path.suffix) as temporary:
        figure.savefig(temporary, format=path.suffix[1:].lower(), dpi=150)
    return path


def check_plot_target(path: str | Path, x_key: str | None, axis_keys: Sequence[str], *,
                      property: str | None = None,
                      properties: Collection[str] | None = None) -> None:
    """Check a plot's file type, folder, x axis and property before any work is done.

    :param x_key: the ``--plot-x`` key, or None (chosen from the data).
    :param axis_keys: the varied keys.
    :param property: the ``--plot-property`` name, or None (the first).
    :param properties: the config's property names, to check *property* against.
    :raises ConfigError: on a missing or unsupported suffix, a folder that does not
        exist, an unwritable place, an *x_key* not varied or an unknown *property*.
    """
    path = Path(path)
    _check_suffix(path)
    _check_writable(path)
    _check_x(x_key, axis_keys)
    if property is not None and properties is not None:
        _check_property(property, list(properties))


def plot_suffixes() -> tuple[str, ...]:
    """The suffixes a plot may have: matplotlib's file types (``.pgf`` only with its TeX)."""
    types = FigureCanvasBase.get_supported_filetypes()
    tex = shutil.which(str(rcParams["pgf.texsystem"])) is not None
    return tuple(f".{t}" for t in sorted(types) if t != "pgf" or tex)


def axis_keys(frame: pd.DataFrame) -> list[str]:
    """The varied keys of a sweep frame, in ``--vary`` order."""
    return [str(c) for c in frame.columns if c not in _NON_AXIS]


def sweep_figure(frame: pd.DataFrame, x_key: str | None, property: str, *,
                 properties: Mapping[str, str] | None = None) -> Figure:
    """The figure of *property* against *x_key*: one line per combination of the other keys.

    :param x_key: the varied key on x; None: the first whose values are all numbers
        (else the first). A non-numeric key is drawn at evenly spaced ticks.
    :param properties: the config's properties (name → PRISM formula). A ``P=?`` or
        ``S=?`` property is drawn on a y axis from 0 to 1; without *properties* the
        kind is unknown and the y axis fits the values.
    :raises ConfigError: when *x_key* is not varied or *property* is unknown.
    """
    keys = axis_keys(frame)
    _check_x(x_key, keys)
    _check_property(property, list(properties or _frame_properties(frame)))
    x = x_key or next((k for k in keys if _numeric(frame[k])), keys[0])
    formula = (properties or {}).get(property)
    figure = Figure(figsize=(7.5, 4.5), layout="constrained")
    FigureCanvasAgg(figure)
    ax = figure.add_subplot()
    rows = _plotted_rows(frame, property)
    _draw(ax, frame, rows, x, [k for k in keys if k != x])
    _style_y(ax, rows, formula)
    ax.set_xlabel(key_label(x))
    ax.set_ylabel(property_label(property, formula))
    _note_missing(ax, frame, rows)
    return figure


def _check_suffix(path: Path) -> None:
    suffixes = plot_suffixes()
    if path.suffix.lower() not in suffixes:
        what = (f"unsupported file type {path.suffix!r}" if path.suffix else
                "no file type (suffix)")
        raise ConfigError(f"--plot {str(path)!r}: {what}; use one of {', '.join(suffixes)}")


def _check_writable(path: Path) -> None:
    folder = path.parent
    if not folder.is_dir():
        raise ConfigError(f"--plot {str(path)!r}: folder {str(folder)!r} does not exist")
    if path.is_dir():
        raise ConfigError(f"--plot {str(path)!r}: is a folder; name a file in it")
    if not os.access(path if path.exists() else folder, os.W_OK):
        raise ConfigError(f"--plot {str(path)!r}: cannot write there (permission denied)")


def _check_x(x_key: str | None, keys: Sequence[str]) -> None:
    if x_key is not None and x_key not in keys:
        raise ConfigError(f"--plot-x: {x_key!r} is not a varied key ({', '.join(keys)})")


def _check_property(name: str, names: list[str]) -> None:
    if name not in names:
        raise ConfigError(f"--plot-property: no property {name!r} (have: {', '.join(names)})")


def _frame_properties(frame: pd.DataFrame) -> list[str]:
    return [str(name) for name in frame["property"].dropna().drop_duplicates()]


def _numeric(column: pd.Series) -> bool:
    """Every value is a finite real number (booleans are not numbers here)."""
    return len(column) > 0 and all(_is_number(v) for v in column)


def _is_number(value: object) -> bool:
    return (isinstance(value, numbers.Real) and not isinstance(value, bool)
            and math.isfinite(value))


def _plotted_rows(frame: pd.DataFrame, prop: str) -> pd.DataFrame:
    """The rows of *prop* with a finite value, in a float column ``y`` (booleans as 0/1)."""
    rows = frame[(frame["property"] == prop) & frame["error"].isna()].copy()
    rows["y"] = [_y(v) for v in rows["value"]]
    return rows[[math.isfinite(y) for y in rows["y"]]]


def _y(value: object) -> float:
    if isinstance(value, bool | numbers.Real):
        return float(value)
    return math.nan


def _draw(ax: Axes, frame: pd.DataFrame, rows: pd.DataFrame, x: str, others: list[str]) -> None:
    """One line per combination of *others* (grid order; none for a combination that
    has no value), points in x order; a non-numeric *x* at evenly spaced ticks."""
    ticks = None if _numeric(frame[x]) else list(dict.fromkeys(frame[x]))
    at = {value: float(i) for i, value in enumerate(ticks or ())}
    combos = _combos(frame, others)
    for i, combo in enumerate(combos):
        line = rows[_matches(rows, others, combo)]
        xs = (line[x].map(at) if ticks else line[x]).astype(float)
        if not line.empty:
            _line(ax, i, xs, line["y"], ", ".join(map(_text, combo)))
    if ticks is not None:
        _categories(ax, ticks)
    else:
        _grid_ticks(ax, sorted(set(frame[x])))
    if others:
        _legend(ax, ", ".join(map(key_label, others)))
    ax.grid(True, alpha=0.3)


def _line(ax: Axes, index: int, xs: pd.Series, ys: pd.Series, label: str) -> None:
    """The *index*-th line: its colour, dash and marker; above the frame, whose top is
    where P = 1 points lie."""
    order = xs.argsort(kind="stable")
    ax.plot(xs.iloc[order], ys.iloc[order], color=f"C{index % 10}",
            linestyle=_STYLES[index % len(_STYLES)], marker=_MARKERS[index % len(_MARKERS)],
            markersize=5 if len(xs) <= 25 else 3 if len(xs) <= 80 else 1.5, linewidth=1.4,
            label=label, clip_on=False, zorder=3)


def _grid_ticks(ax: Axes, values: list[float]) -> None:
    """Ticks at the values of an evenly spaced grid of a few points (``12, 12.2, 12.4``,
    not ``12.00, 12.05, …``); denser or uneven grids keep matplotlib's ticks."""
    steps = {round(b - a, 9) for a, b in itertools.pairwise(values)}
    if 1 < len(values) <= _GRID_TICKS and len(steps) == 1:
        ax.set_xticks(values, [_text(v) for v in values])


def _categories(ax: Axes, ticks: list[Hashable]) -> None:
    labels = [_text(v) for v in ticks]
    ax.set_xticks(range(len(ticks)), labels, rotation=30 if sum(map(len, labels)) > 60 else 0)
    ax.set_xlim(-0.5, len(ticks) - 0.5)


def _combos(frame: pd.DataFrame, others: list[str]) -> list[tuple[Hashable, ...]]:
    if not others:
        return [()]
    return list(frame[others].drop_duplicates().itertuples(index=False, name=None))


def _matches(rows: pd.DataFrame, keys: list[str], combo: tuple[Hashable, ...]) -> pd.Series:
    mask = pd.Series(True, index=rows.index)
    for key, value in zip(keys, combo, strict=True):
        mask &= rows[key] == value
    return mask


def _legend(ax: Axes, title: str) -> None:
    """Beside the axes (inside, it would hide points: markers at P = 1 sit on the frame),
    in columns of :data:`_LEGEND_ROWS`; past :data:`_LEGEND_MOST` lines, the first ones
    and how many more (a legend of hundreds would crowd out the plot)."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    if len(handles) > _LEGEND_MOST:
        more = len(handles) - _LEGEND_MOST + 1
        handles = [*handles[:_LEGEND_MOST - 1], Line2D([], [], linestyle="none")]
        labels = [*labels[:_LEGEND_MOST - 1], f"… and {more} more"]
    ax.legend(handles, labels, title=title, fontsize="small", title_fontsize="small",
              loc="upper left", bbox_to_anchor=(1.01, 1),
              ncols=math.ceil(len(handles) / _LEGEND_ROWS))


def _style_y(ax: Axes, rows: pd.DataFrame, formula: str | None) -> None:
    """A probability (or a yes/no verdict) from 0 to 1 exactly; anything else fits."""
    if len(rows) and all(isinstance(v, bool) for v in rows["value"]):
        ax.set_ylim(0, 1)
        ax.set_yticks([0, 1], ["false", "true"])
    elif formula is not None and _is_probability(formula):
        ax.set_ylim(0, 1)


def _is_probability(formula: str) -> bool:
    """``P=? [...]`` or ``S=? [...]``: a value in [0, 1]."""
    try:
        parsed = parse_property(formula).formula
    except VeribatteryError:
        return False
    return isinstance(parsed, ProbOp | SteadyOp) and parsed.op == "=?"


def _note_missing(ax: Axes, frame: pd.DataFrame, rows: pd.DataFrame) -> None:
    """Say above the plot how many points are not drawn, and why."""
    total = frame["point"].nunique()
    failed = frame.loc[frame["error"].notna(), "point"].nunique()
    other = total - failed - rows["point"].nunique()
    parts = [text for count, text in ((failed, f"{failed} failed"),
                                      (other, f"{other} without a finite value")) if count]
    if parts:
        ax.set_title(f"not drawn: {' and '.join(parts)} of {total} points", loc="right",
                     fontsize="small", color="tab:red")


def _text(value: object) -> str:
    """A grid value as the user wrote it: ``12``, ``12.2``, ``advanced``, ``true``."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)
