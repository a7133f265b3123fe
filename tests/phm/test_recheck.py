"""recheck and forecast on a small farm: values equal independent checks, exit codes, crossing."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from tests.phm.helpers import EXAMPLES, cycles_csv
from veribattery.config import load_config, parse_requirement
from veribattery.mission import check_mission
from veribattery.phm.data import read_cycles
from veribattery.phm.forecast import forecast, grid_ages
from veribattery.phm.recheck import recheck
from veribattery.phm.refit import RechargeCapError

SMALL = ("farm.cols=3", "farm.rows=3", "farm.base=[0,0]")


def _config(tmp_path: Path, capacity: str = "11", requirement: str = "p_success >= 0.99") -> Path:
    path = tmp_path / "mission.yaml"
    path.write_text(f"battery:\n  capacity_ah: {capacity}  # new\n  max_recharges: 50\n"
                    "requirements:\n"
                    f"  - {requirement}\n")
    return path


def test_recheck_regression(tmp_path: Path) -> None:
    cycles = np.arange(0, 101, 10.0)
    log = cycles_csv(tmp_path / "c.csv", cycles, 6.0 - 0.03 * cycles)  # 3 Ah at cycle 100
    result = recheck(_config(tmp_path), log, overrides=SMALL)
    assert [m.key for m in result.moved][:2] == ["battery.capacity_ah",
                                                 "battery.fade_per_recharge"]
    assert result.moved[0].before == Fraction(11) and result.moved[0].after == Fraction(3)
    # fade at cycle 100 = b / C(100) = 0.03 / 3 = 0.01 per recharge
    assert result.moved[1].after == Fraction(1, 100)
    # The "after" values are those of the config with the two keys set by hand.
    by_hand = check_mission(load_config(_config(tmp_path), [
        *SMALL, "battery.capacity_ah=3", "battery.fade_per_recharge=0.01"]))
    assert result.after.values == by_hand.values
    before = check_mission(load_config(_config(tmp_path), SMALL))
    assert result.before.values == before.values
    assert before.all_requirements_hold and not by_hand.all_requirements_hold
    assert result.regressions == ("p_success >= 0.99",)


def test_recheck_no_regression_when_it_failed_before(tmp_path: Path) -> None:
    cycles = np.arange(0, 101, 10.0)
    log = cycles_csv(tmp_path / "c.csv", cycles, 6.0 - 0.03 * cycles)
    result = recheck(_config(tmp_path, capacity="2"), log, overrides=SMALL)
    assert not result.before.all_requirements_hold
    assert result.regressions == ()


def test_grid_ages() -> None:
    assert grid_ages(300, 30) == list(range(0, 301, 30))
    assert grid_ages(10, 4) == [0, 4, 8, 10]


def _fails(config: Path, ahead: int) -> bool:
    """Check one age independently: C(n) = 8.6 - 0.032 n at cycle 50 + ahead (the slope
    keeps every integer age off a 0.05 Ah rounding tie)."""
    capacity = 8.6 - 0.032 * (50 + ahead)
    fade = Fraction(f"{0.032 / capacity:.2e}")  # three significant digits
    cfg = load_config(config, [*SMALL, f"battery.capacity_ah={round(capacity, 1)}",
                               f"battery.fade_per_recharge={float(fade)}"])
    return not check_mission(cfg).all_requirements_hold


def test_forecast_crossing_matches_independent_checks(tmp_path: Path) -> None:
    """Grid ages agree with independent checks; the bisected crossing is the first
    failing age of its bracket, checked age by age."""
    cycles = np.arange(0, 51, 5.0)
    log_path = cycles_csv(tmp_path / "c.csv", cycles, 8.6 - 0.032 * cycles)  # 7.0 Ah now
    config = _config(tmp_path)
    result = forecast(config, read_cycles(log_path), parse_requirement("p_success >= 0.99"),
                      horizon=20, step=5, overrides=SMALL)
    grid = {p.ahead: p for p in result.points if p.ahead % 5 == 0}
    assert sorted(grid) == [0, 5, 10, 15, 20]
    assert grid[0].capacity_ah == Fraction(7) and grid[20].capacity_ah == Fraction(64, 10)
    for ahead in (0, 20):
        assert grid[ahead].holds == (not _fails(config, ahead))
    assert result.fails_after is not None and 0 < result.fails_after <= 20
    bracket_start = max(a for a in grid if a < result.fails_after)
    first = next(a for a in range(bracket_start, 21) if _fails(config, a))
    assert result.fails_after == first


def test_examples_exist_with_command_headers() -> None:
    for name in ("cycles.csv", "discharge.csv"):
        head = (EXAMPLES / name).read_text().splitlines()[:2]
        assert head[0].startswith("# ") and "veribattery phm simulate" in head[1]


def test_recheck_on_examples() -> None:
    model = "exponential"
    result = recheck(EXAMPLES / "mission.yaml", EXAMPLES / "cycles.csv",
                     EXAMPLES / "discharge.csv", overrides=SMALL, model=model)
    keys = [m.key for m in result.moved]
    assert "battery.voltage_thresholds.low" in keys
    assert result.refit.fade.fit.name == model
    assert result.refit.fade.capacity_ah == Fraction(95, 10)


def test_fade_too_fast_for_max_recharges(tmp_path: Path) -> None:
    cycles = np.arange(0, 101, 10.0)
    log = cycles_csv(tmp_path / "c.csv", cycles, 6.0 - 0.03 * cycles)  # fade 0.01 at 100
    path = tmp_path / "m.yaml"
    path.write_text("battery:\n  max_recharges: 200\n")
    # The config's key is at fault, not the log's last row (as it was blamed).
    with pytest.raises(RechargeCapError, match=r"^battery.max_recharges: 200 recharges x the "
                       r"fitted fade 0.01/recharge >= 1, .*; it must be at most 99$") as caught:
        recheck(path, log, overrides=SMALL)
    assert (caught.value.max_recharges, caught.value.largest) == (200, 99)
