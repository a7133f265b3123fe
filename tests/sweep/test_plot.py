"""Sweep figures: what is drawn (checked on the matplotlib Figure), labels, and the target.

The frames are built as :func:`run_sweep` builds them (:func:`point_rows` of each point's
:class:`PointResult`), without checking a model.
"""

from __future__ import annotations

import itertools
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from veribattery._files import new_file_mode
from veribattery.errors import ConfigError
from veribattery.sweep.labels import key_label, property_label
from veribattery.sweep.plot import check_plot_target, plot_suffixes, plot_sweep, sweep_figure
from veribattery.sweep.run import FIXED_COLUMNS, point_rows
from veribattery.sweep.tasks import PointResult, PropertyValue

MODELS = ("advanced", "basic_high")
CAPACITIES = (12, 12.2, 12.4)
KEYS = ("battery.model", "battery.capacity_ah")
#: The config's properties: names do not say which are probabilities, formulas do.
PROPERTIES = {
    "p_success": 'P=? [ F "success" ]',
    "exp_mission_time": 'R{"mt"}=? [ F "done" ]',
    "reach": 'P=? [ F "done" ]',
    "verdict": 'P>=0.9 [ F "success" ]',
}


def value(name: str, index: int) -> float | bool:
    """The synthetic value of property *name* at grid point *index*."""
    return {"p_success": 0.9 + 0.01 * index, "exp_mission_time": 1000.0 + 10 * index,
            "reach": 0.5, "verdict": index % 2 == 0}[name]


def result(index: int, failed: bool, undefined: frozenset[str]) -> PointResult:
    if failed:
        return PointResult(index, error="worker killed (signal 9)")
    values = tuple(PropertyValue(name, math.nan if name in undefined else value(name, index),
                                 None, None) for name in PROPERTIES)
    return PointResult(index, values, states=10, transitions=20, seconds=0.1,
                       recharge_cap_probability=0.0)


def sweep_frame(keys: tuple[str, ...] = KEYS, failed: frozenset[int] = frozenset(),
                undefined: dict[int, frozenset[str]] | None = None) -> pd.DataFrame:
    """The frame of the grid MODELS x CAPACITIES (the keys of *keys* only)."""
    grid: dict[str, tuple[object, ...]] = {"battery.model": MODELS,
                                           "battery.capacity_ah": CAPACITIES}
    combos = itertools.product(*(grid[k] for k in keys))
    points: list[dict[str, object]] = [dict(zip(keys, c, strict=True)) for c in combos]
    rows = [row for i, point in enumerate(points) for row in point_rows(
        result(i, i in failed, (undefined or {}).get(i, frozenset())), point)]
    frame = pd.DataFrame(rows, columns=["point", *keys, *FIXED_COLUMNS])
    frame["holds"] = frame["holds"].astype("boolean")
    return frame


def axes_of(figure: Figure) -> Axes:
    (ax,) = figure.axes
    return ax


def xs(line: Line2D) -> list[float]:
    return [float(x) for x in np.asarray(line.get_xdata(), dtype=float)]


def ys(line: Line2D) -> list[float]:
    return [float(y) for y in np.asarray(line.get_ydata(), dtype=float)]


def legend_of(ax: Axes) -> tuple[str, list[str]]:
    legend = ax.get_legend()
    assert legend is not None
    return legend.get_title().get_text(), [t.get_text() for t in legend.get_texts()]


def test_numeric_key_on_x_and_a_line_per_category() -> None:
    ax = axes_of(sweep_figure(sweep_frame(), None, "p_success", properties=PROPERTIES))
    lines = ax.get_lines()
    assert [line.get_label() for line in lines] == list(MODELS)
    for m, line in enumerate(lines):
        assert xs(line) == list(CAPACITIES)
        expected = [value("p_success", 3 * m + c) for c in range(3)]
        assert ys(line) == pytest.approx(expected, rel=1e-12)
        assert line.get_marker() not in (None, "None", "")
    assert legend_of(ax) == ("battery model", list(MODELS))
    assert ax.get_ylim() == (0, 1)
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("battery capacity (Ah)", "P(success)")
    assert [t.get_text() for t in ax.get_xticklabels()] == ["12", "12.2", "12.4"]


def test_first_numeric_key_is_chosen_whatever_its_place() -> None:
    frame = sweep_frame(keys=("battery.capacity_ah", "battery.model"))
    ax = axes_of(sweep_figure(frame, None, "exp_mission_time", properties=PROPERTIES))
    assert ax.get_xlabel() == "battery capacity (Ah)"
    assert legend_of(ax) == ("battery model", list(MODELS))


def test_a_chosen_category_on_x_is_drawn_at_evenly_spaced_ticks() -> None:
    ax = axes_of(sweep_figure(sweep_frame(), "battery.model", "p_success",
                              properties=PROPERTIES))
    lines = ax.get_lines()
    assert [line.get_label() for line in lines] == ["12", "12.2", "12.4"]
    assert all(xs(line) == [0, 1] for line in lines)
    assert [t.get_text() for t in ax.get_xticklabels()] == list(MODELS)
    assert list(ax.get_xticks()) == [0, 1]
    assert legend_of(ax)[0] == "battery capacity (Ah)"
    assert ax.get_xlabel() == "battery model"


def test_a_reward_axis_fits_its_values_with_units() -> None:
    ax = axes_of(sweep_figure(sweep_frame(), None, "exp_mission_time", properties=PROPERTIES))
    low, high = ax.get_ylim()
    assert 900 < low <= 1000 and 1050 <= high < 1100
    assert ax.get_ylabel() == "expected mission time (min)"


@pytest.mark.parametrize(
    ("name", "formulas", "ylim", "label"),
    [
        ("reach", PROPERTIES, (0, 1), "reach"),
        ("p_success", {**PROPERTIES, "p_success": 'R{"mt"}=? [ F "done" ]'}, None, "p_success"),
        ("p_success", None, None, "P(success)"),
    ],
    ids=["probability-by-formula", "p-prefix-but-reward", "formula-unknown"],
)
def test_probability_axis_follows_the_formula_not_the_name(
    name: str, formulas: dict[str, str] | None, ylim: tuple[int, int] | None, label: str
) -> None:
    ax = axes_of(sweep_figure(sweep_frame(), None, name, properties=formulas))
    assert (ax.get_ylim() == (0, 1)) == (ylim is not None)
    assert ax.get_ylabel() == label


def test_a_verdict_is_drawn_as_false_and_true() -> None:
    ax = axes_of(sweep_figure(sweep_frame(), None, "verdict", properties=PROPERTIES))
    assert ax.get_ylim() == (0, 1)
    assert [t.get_text() for t in ax.get_yticklabels()] == ["false", "true"]
    assert ys(ax.get_lines()[0]) == [1.0, 0.0, 1.0]


def test_failed_points_are_left_out_and_counted() -> None:
    frame = sweep_frame(failed=frozenset({1, 5}))
    ax = axes_of(sweep_figure(frame, None, "p_success", properties=PROPERTIES))
    advanced, basic = ax.get_lines()
    assert xs(advanced) == [12, 12.4]
    assert xs(basic) == [12, 12.2]
    assert 0 not in [*ys(advanced), *ys(basic)]
    assert ax.get_title(loc="right") == "not drawn: 2 failed of 6 points"


def test_points_without_a_value_are_left_out_and_counted() -> None:
    frame = sweep_frame(undefined={0: frozenset({"p_success"})}, failed=frozenset({3}))
    ax = axes_of(sweep_figure(frame, None, "p_success", properties=PROPERTIES))
    assert xs(ax.get_lines()[0]) == [12.2, 12.4]
    assert ax.get_title(loc="right") == (
        "not drawn: 1 failed and 1 without a finite value of 6 points")


def test_a_combination_with_no_value_draws_no_line() -> None:
    ax = axes_of(sweep_figure(sweep_frame(failed=frozenset({0, 1, 2})), None, "p_success",
                              properties=PROPERTIES))
    assert [line.get_label() for line in ax.get_lines()] == ["basic_high"]


def test_one_varied_key_draws_one_line_and_no_legend() -> None:
    ax = axes_of(sweep_figure(sweep_frame(keys=("battery.capacity_ah",)), None, "p_success"))
    (line,) = ax.get_lines()
    assert xs(line) == list(CAPACITIES)
    assert ax.get_legend() is None
    assert ax.get_title(loc="right") == ""


def test_a_legend_of_hundreds_names_the_first_and_counts_the_rest() -> None:
    rows = [row for i in range(300) for row in point_rows(
        PointResult(i, (PropertyValue("p_success", 0.5, None, None),)),
        {"strategy.safe_t": 0.3, "battery.capacity_ah": 5 + i})]
    frame = pd.DataFrame(rows, columns=["point", "strategy.safe_t", "battery.capacity_ah",
                                        *FIXED_COLUMNS])
    ax = axes_of(sweep_figure(frame, None, "p_success"))
    assert ax.get_xlabel() == "safety threshold safe_t (SOC)"
    assert len(ax.get_lines()) == 300
    title, entries = legend_of(ax)
    assert title == "battery capacity (Ah)"
    assert entries[:2] == ["5", "6"] and entries[-1] == "… and 261 more" and len(entries) == 40


@pytest.mark.parametrize("suffix", [".png", ".svg", ".pdf", ".PNG"])
def test_plot_sweep_writes_atomically_with_the_umask_mode(tmp_path: Path, suffix: str) -> None:
    path = plot_sweep(sweep_frame(), None, "p_success", tmp_path / f"fig{suffix}",
                      properties=PROPERTIES)
    magic = {".png": b"\x89PNG", ".svg": b"<?xml", ".pdf": b"%PDF"}[suffix.lower()]
    assert path.read_bytes().startswith(magic)
    assert os.stat(path).st_mode & 0o7777 == new_file_mode()
    assert list(tmp_path.iterdir()) == [path]


def test_a_replaced_figure_keeps_its_mode(tmp_path: Path) -> None:
    path = tmp_path / "fig.png"
    path.write_bytes(b"old")
    path.chmod(0o640)
    plot_sweep(sweep_frame(), None, "p_success", path)
    assert path.read_bytes().startswith(b"\x89PNG") and path.stat().st_mode & 0o7777 == 0o640


def test_a_failed_write_leaves_the_old_file_and_no_temporary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "fig.png"
    path.write_bytes(b"old")

    def fail(*_: object, **__: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(Figure, "savefig", fail)
    with pytest.raises(OSError, match="disk full"):
        plot_sweep(sweep_frame(), None, "p_success", path)
    assert list(tmp_path.iterdir()) == [path] and path.read_bytes() == b"old"


@pytest.mark.parametrize(
    ("target", "x_key", "prop", "message"),
    [
        ("x.xyz", None, None, r"unsupported file type '\.xyz'; use one of .*\.pdf.*\.png.*\.svg"),
        ("plot", None, None, r"no file type \(suffix\); use one of .*\.png"),
        ("missing/x.png", None, None, r"folder '.*missing' does not exist"),
        (".", None, None, "no file type"),
        ("sub", None, None, "unsupported file type|no file type"),
        ("x.png", "farm.cols", None, "'farm.cols' is not a varied key"),
        ("x.png", None, "nope", r"no property 'nope' \(have: p_success, exp_mission_time, "),
    ],
    ids=["unknown-suffix", "no-suffix", "no-folder", "dot", "folder", "x-not-varied",
         "unknown-property"],
)
def test_a_bad_target_is_refused_before_anything_is_written(
    tmp_path: Path, target: str, x_key: str | None, prop: str | None, message: str
) -> None:
    (tmp_path / "sub").mkdir()
    before = sorted(tmp_path.rglob("*"))
    path = tmp_path / target
    with pytest.raises(ConfigError, match=message) as caught:
        check_plot_target(path, x_key, KEYS, property=prop, properties=PROPERTIES)
    assert "\n" not in str(caught.value)
    with pytest.raises(ConfigError, match=message):
        plot_sweep(sweep_frame(), x_key, prop or "p_success", path, properties=PROPERTIES)
    assert sorted(tmp_path.rglob("*")) == before


def test_a_folder_named_like_a_figure_is_refused(tmp_path: Path) -> None:
    (tmp_path / "fig.png").mkdir()
    with pytest.raises(ConfigError, match="is a folder"):
        check_plot_target(tmp_path / "fig.png", None, KEYS)


def test_without_properties_the_frame_names_the_known_ones(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"no property 'nope' \(have: p_success, "):
        plot_sweep(sweep_frame(), None, "nope", tmp_path / "fig.png")
    check_plot_target(tmp_path / "fig.png", "battery.model", KEYS, property="nope")
    assert list(tmp_path.iterdir()) == []


def test_suffixes_are_what_matplotlib_writes() -> None:
    suffixes = plot_suffixes()
    assert {".png", ".pdf", ".svg", ".eps"} <= set(suffixes)
    assert all(s.startswith(".") and s == s.lower() for s in suffixes)


@pytest.mark.parametrize(
    ("key", "label"),
    [
        ("battery.capacity_ah", "battery capacity (Ah)"),
        ("battery.resolution_ah", "charge resolution (Ah)"),
        ("times_min.recharge", "recharge time (min)"),
        ("battery.consumption.cell.low", "cell crossing consumption, low voltage (Ah)"),
        ("battery.consumption.voltages_v.high", "high voltage (V)"),
        ("farm.spacing_m", "turbine spacing (m)"),
        ("properties.p_success", "properties.p_success"),
        ("no.such_key", "no.such_key"),
    ],
)
def test_key_labels(key: str, label: str) -> None:
    assert key_label(key) == label


@pytest.mark.parametrize(
    ("name", "formula", "label"),
    [
        ("p_success", None, "P(success)"),
        ("p_success", 'P=?[F "success"]', "P(success)"),
        ("p_success", 'P=? [ F "done" ]', "p_success"),
        ("exp_mission_time", None, "expected mission time (min)"),
        ("exp_recharges", None, "expected recharges"),
        ("mine", 'P=? [ F "done" ]', "mine"),
    ],
)
def test_property_labels(name: str, formula: str | None, label: str) -> None:
    assert property_label(name, formula) == label
