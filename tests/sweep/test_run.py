"""run_sweep against check_mission at the same points, on a small (3x3) farm."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

import veribattery.sweep as sweep
from veribattery.config import load_config
from veribattery.errors import ConfigError
from veribattery.mission import check_mission
from veribattery.sweep import any_requirement_fails, parse_axis, records, run_sweep, wide
from veribattery.sweep.run import FIXED_COLUMNS

SMALL_FARM = ("farm.cols=3", "farm.rows=3", "farm.base=[0,0]")
REQUIREMENT = 'requirements=["exp_recharges < 10"]'


@pytest.fixture(scope="module")
def frame() -> pd.DataFrame:
    axes = [parse_axis("battery.capacity_ah=10:10.5:0.5"), parse_axis("strategy.safe_t=0.3")]
    calls: list[tuple[int, int]] = []
    overrides = [*SMALL_FARM, REQUIREMENT]
    result = run_sweep("", axes, overrides, progress=lambda d, n: calls.append((d, n)))
    assert calls == [(0, 2), (1, 2), (2, 2)]
    return result


def test_public_api() -> None:
    assert sorted(sweep.__all__) == sweep.__all__
    for name in sweep.__all__:
        assert hasattr(sweep, name)


def test_tidy_shape(frame: pd.DataFrame) -> None:
    assert list(frame.columns) == [
        "point", "battery.capacity_ah", "strategy.safe_t", *FIXED_COLUMNS,
    ]
    assert len(frame) == 2 * 5  # points x properties (3 of the paper, 2 conditional)
    assert list(frame["property"][:3]) == ["p_success", "exp_mission_time", "exp_recharges"]
    assert list(frame["battery.capacity_ah"].drop_duplicates()) == [10, 10.5]


@pytest.mark.parametrize("capacity", ["10", "10.5"])
def test_values_equal_check_mission(frame: pd.DataFrame, capacity: str) -> None:
    # The independent path: load and check the point directly, as `check` does.
    overrides = [*SMALL_FARM, REQUIREMENT, f"battery.capacity_ah={capacity}", "strategy.safe_t=0.3"]
    report = check_mission(load_config("", overrides))
    rows = frame[frame["battery.capacity_ah"] == float(capacity)]
    assert dict(zip(rows["property"], rows["value"], strict=True)) == pytest.approx(report.values)
    assert set(rows["states"]) == {report.run.dtmc.num_states}
    assert set(rows["transitions"]) == {report.run.dtmc.num_transitions}
    judged = rows.dropna(subset=["holds"])
    assert list(judged["property"]) == ["exp_recharges"]
    assert list(judged["requirement"]) == ["exp_recharges < 10"]
    assert bool(judged["holds"].iloc[0]) == report.all_requirements_hold


def test_requirements_and_wide(frame: pd.DataFrame) -> None:
    # exp_recharges is 10.11 at 10 Ah and 9.88 at 10.5 Ah on this farm.
    assert any_requirement_fails(frame)
    assert not any_requirement_fails(frame[frame["point"] == 1])
    table = wide(frame, ["battery.capacity_ah", "strategy.safe_t"])
    assert list(table.columns) == [
        "battery.capacity_ah", "strategy.safe_t", "states", "transitions",
        "p_success", "exp_mission_time", "exp_recharges", "exp_mission_time_given_success",
        "exp_recharges_given_success", "requirements",
    ]
    assert list(table["requirements"]) == ["FAIL", "PASS"]
    assert (frame["seconds"] > 0).all()


def test_records_are_plain(frame: pd.DataFrame) -> None:
    first = records(frame)[0]
    assert first["holds"] is None and first["requirement"] is None
    assert isinstance(first["states"], int)


def test_bad_value_at_a_point_fails_before_checking() -> None:
    axes = [parse_axis("strategy.safe_t=0.3,1.5")]
    with pytest.raises(ConfigError, match=r"^at strategy.safe_t=1.5: .*strategy.safe_t"):
        run_sweep("", axes, SMALL_FARM, progress=lambda d, n: pytest.fail("checked a point"))


def test_plot_rejects_unknown_names(frame: pd.DataFrame, tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not a varied key"):
        sweep.plot_sweep(frame, "battery.model", "p_success", tmp_path / "a.png")
    with pytest.raises(ConfigError, match="unsupported file type"):
        sweep.plot_sweep(frame, "battery.capacity_ah", "p_success", tmp_path / "a.txt")
    with pytest.raises(ConfigError, match="no property 'nope'"):
        sweep.plot_sweep(frame, "battery.capacity_ah", "nope", tmp_path / "a.png")
    assert list(tmp_path.iterdir()) == []


def test_plot_one_line_per_other_axis(frame: pd.DataFrame, tmp_path: Path) -> None:
    path = sweep.plot_sweep(frame, "battery.capacity_ah", "exp_recharges", tmp_path / "r.pdf")
    assert path.read_bytes().startswith(b"%PDF")
