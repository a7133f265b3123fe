"""Run the mission pipeline at every grid point and collect one tidy DataFrame.

The frame has one row per grid point x property, with columns

``point``
    the 0-based index of the grid point (grid order: the first axis varies slowest);
*each axis key* (e.g. ``battery.capacity_ah``)
    the value at that point (lists such as ``farm.base`` as their YAML text, ``[0, 0]``);
``property``, ``value``
    the property's name and its value at the initial state;
``states``, ``transitions``
    the size of the point's DTMC;
``seconds``
    wall-clock seconds for the point (load, render, parse, build, check);
``requirement``, ``holds``
    the config's requirements on this property (joined by `` and ``) and whether all of
    them hold; ``None`` and ``<NA>`` when no requirement names the property.

``frame.attrs["warnings"]`` holds the model warnings of every point, each prefixed with
the point (``battery.capacity_ah=10: …``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd

from veribattery.config import MissionConfig, load_config
from veribattery.errors import VeribatteryError
from veribattery.mission import MissionReport, check_mission
from veribattery.sweep.grid import Axis, Point, grid, point_overrides, yaml_text

__all__ = [
    "FIXED_COLUMNS",
    "SweepProgress",
    "any_requirement_fails",
    "records",
    "run_sweep",
    "wide",
]

#: Called with (points done, total points): once with 0 before the first, then after each.
SweepProgress = Callable[[int, int], None]

#: The columns after the axis keys, in order.
FIXED_COLUMNS = ("property", "value", "states", "transitions", "seconds", "requirement", "holds")


def run_sweep(
    config: str | Path,
    axes: Sequence[Axis],
    overrides: Sequence[str] = (),
    progress: SweepProgress | None = None,
) -> pd.DataFrame:
    """Check the mission *config* at every point of the grid of *axes*.

    Every point's config is loaded and validated before any is checked, so a bad value
    fails at once rather than after hours of checking.

    :param config: the config file (or YAML text, as :func:`load_config` takes).
    :param axes: the swept keys; their values override *overrides*.
    :param overrides: ``KEY=VALUE`` strings applied at every point (``--set``).
    :param progress: called with (points done, total points).
    :raises ConfigError: when the config is invalid at some point (naming the point).
    """
    points = grid(axes)
    configs = [_load(config, overrides, point) for point in points]
    rows: list[dict[str, object]] = []
    warnings: list[str] = []
    if progress is not None:
        progress(0, len(points))
    for index, (point, cfg) in enumerate(zip(points, configs, strict=True)):
        started = time.perf_counter()
        report = check_mission(cfg)
        seconds = time.perf_counter() - started
        rows.extend(_rows(index, point, report, seconds))
        warnings.extend(f"{_describe(point)}: {w}" for w in report.warnings)
        if progress is not None:
            progress(index + 1, len(points))
    return _frame(rows, [axis.key for axis in axes], warnings)


def _load(config: str | Path, overrides: Sequence[str], point: Point) -> MissionConfig:
    try:
        return load_config(config, [*overrides, *point_overrides(point)])
    except VeribatteryError as exc:
        if not point:
            raise
        raise type(exc)(f"at {_describe(point)}: {exc.message}", exc.span) from None


def _describe(point: Point) -> str:
    return ", ".join(f"{key}={yaml_text(value)}" for key, value in point.items()) or "the config"


def _rows(
    index: int, point: Point, report: MissionReport, seconds: float
) -> list[dict[str, object]]:
    dtmc = report.run.dtmc
    cells = {key: yaml_text(v) if isinstance(v, tuple) else v for key, v in point.items()}
    rows = []
    for name, value in report.values.items():
        outcomes = [o for o in report.requirements if o.requirement.prop == name]
        rows.append({
            "point": index, **cells, "property": name, "value": value,
            "states": dtmc.num_states, "transitions": dtmc.num_transitions, "seconds": seconds,
            "requirement": " and ".join(str(o.requirement) for o in outcomes) or None,
            "holds": all(o.holds for o in outcomes) if outcomes else None,
        })
    return rows


def _frame(rows: list[dict[str, object]], keys: list[str], warnings: list[str]) -> pd.DataFrame:
    frame = pd.DataFrame(rows, columns=["point", *keys, *FIXED_COLUMNS])
    frame["holds"] = frame["holds"].astype("boolean")
    frame.attrs["warnings"] = tuple(warnings)
    return frame


def any_requirement_fails(frame: pd.DataFrame) -> bool:
    """True when some requirement fails at some point of a :func:`run_sweep` frame."""
    return bool(frame["holds"].eq(False).any())


def wide(frame: pd.DataFrame, keys: Sequence[str]) -> pd.DataFrame:
    """One row per point: the axis keys, one column per property (in config order), sizes.

    A ``requirements`` column (``PASS``/``FAIL``) is added when the config has requirements.
    """
    first = frame.drop_duplicates("point").set_index("point")
    result = first[[*keys, "states", "transitions"]].copy()
    for name in frame["property"].drop_duplicates():
        rows = frame[frame["property"] == name].set_index("point")
        result[name] = rows["value"]
    judged = frame.dropna(subset=["holds"])
    if not judged.empty:
        holds = judged.groupby("point")["holds"].all()
        result["requirements"] = holds.map({True: "PASS", False: "FAIL"})
    return result.reset_index(drop=True)


def records(frame: pd.DataFrame) -> list[dict[str, object]]:
    """The rows as plain Python dicts (missing values as ``None``), ready for JSON."""
    plain = frame.astype(object).where(frame.notna(), None)
    return [dict(row) for row in plain.to_dict("records")]
