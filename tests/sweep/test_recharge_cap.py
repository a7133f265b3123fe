"""The recharge-cap rule: P[F rc=RC_MAX] always reported, warned about from 1e-9 on."""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.sweep.helpers import SMALL_FARM
from veribattery.cli import cli
from veribattery.config import load_config
from veribattery.mission import (
    RECHARGE_CAP,
    RECHARGE_CAP_WARN_AT,
    MissionReport,
    check_mission,
    mission_files,
)
from veribattery.sweep import parse_axis, run_sweep


def test_cap_probability_matches_a_hand_solved_chain() -> None:
    # Basic model, wind never changes (p_wsp_c=0): every sortie is the same, so the
    # mission needs a fixed number of recharges n. A cap below n cuts every mission
    # (P[F rc=RC_MAX] = 1, P(success) = 0); a cap above n is never reached (P = 0).
    free = check_mission(load_config("", [*SMALL_FARM, "battery.model=basic_high",
                                          "environment.p_wsp_c=0"]))
    needed = free.values["exp_recharges"]
    assert isinstance(needed, float) and Fraction(needed).denominator == 1 and needed >= 2
    n = int(needed)
    cut = check_mission(load_config("", [*SMALL_FARM, "battery.model=basic_high",
                                         "environment.p_wsp_c=0",
                                         f"battery.max_recharges={n - 1}"]))
    assert cut.recharge_cap_probability == 1.0
    assert cut.values["p_success"] == 0.0
    assert len([w for w in cut.warnings if "recharge cap" in w]) == 1
    assert free.recharge_cap_probability == 0.0
    assert not [w for w in free.warnings if "recharge cap" in w]


def test_tiny_probability_is_reported_but_not_warned(tmp_path: Path) -> None:
    # 25 recharges at most (SMALL_FARM): with wind changes the cap is reached with a
    # positive probability below 1e-9, which cannot change a printed result.
    report = check_mission(load_config("", SMALL_FARM))
    assert 0 < report.recharge_cap_probability < RECHARGE_CAP_WARN_AT
    assert not [w for w in report.warnings if "recharge cap" in w]
    # The independent path: Storm's value of the same probability on the emitted model.
    storm = _storm_probability(report)
    assert report.recharge_cap_probability == pytest.approx(storm, rel=1e-6)
    # A named property of the check, read by the report: never among the config's
    # results, nor in the files emit writes.
    assert report.run.internal_value(RECHARGE_CAP) == report.recharge_cap_probability
    assert [r.property.name for r in report.run.results] == list(report.config.properties)
    files = mission_files(report.config)
    assert "rc=" not in files.properties + files.storm_only
    config = tmp_path / "m.yaml"
    config.write_text("")
    result = CliRunner().invoke(cli, ["check", str(config), *_sets(), "--format", "json"])
    doc = json.loads(result.stdout)
    assert doc["recharge_cap_probability"] == report.recharge_cap_probability
    assert "recharge cap" not in result.stderr
    result = CliRunner().invoke(cli, ["check", str(config), *_sets(), "--format", "csv"])
    last = result.stdout.splitlines()[-1]
    assert last == f"recharge_cap_probability,{report.recharge_cap_probability!r}"


def _storm_probability(report: MissionReport) -> float:
    pytest.importorskip("stormpy")
    from tests.storm_oracle import run_storm

    rc_max = report.config.battery.max_recharges
    storm = run_storm(mission_files(report.config).model, f"P=? [ F rc={rc_max} ]")
    value = storm.values[0][storm.initial[0]]
    assert isinstance(value, float)
    return value


def test_sweep_warns_once_with_points_and_largest_probability() -> None:
    free = check_mission(load_config("", [*SMALL_FARM, "battery.model=basic_high",
                                          "environment.p_wsp_c=0"]))
    n = int(free.values["exp_recharges"])
    # At a cap of exactly n the last recharge reaches it: P[F rc=RC_MAX] is 1 there
    # although no mission is cut, so the third point is n + 1.
    axis = parse_axis(f"battery.max_recharges={n - 2},{n - 1},{n + 1}")
    frame = run_sweep("", [axis], [*SMALL_FARM, "battery.model=basic_high",
                                   "environment.p_wsp_c=0"])
    caps = list(frame.drop_duplicates("point")["recharge_cap_probability"])
    assert caps == [1.0, 1.0, 0.0]
    cap_warnings = [w for w in frame.attrs["warnings"] if "recharge cap" in w]
    assert len(cap_warnings) == 1
    assert "probability up to 1 (at battery.max_recharges=" in cap_warnings[0]
    assert "at 2 of 3 points" in cap_warnings[0]


def _sets(*extra: str) -> list[str]:
    return [arg for item in (*SMALL_FARM, *extra) for arg in ("--set", item)]
