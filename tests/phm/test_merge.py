"""The text-level YAML merge keeps comments and layout and gives exactly the intended data."""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path

import pytest
import yaml

from veribattery.config import load_config
from veribattery.phm.data import PhmDataError
from veribattery.phm.merge import merge_text, write_atomic

FADE = {"battery.capacity_ah": Fraction(104, 10), "battery.fade_per_recharge": Fraction(3, 1000)}

CASE1 = """\
# Table 3, case #1 -- the baseline.
battery:
  model: advanced   # the paper's model
  capacity_ah: 11   # new pack
  # fade: from the cycler
  fade_per_recharge: 0.002
strategy:
  safe_t: 0.3 # BS1
"""


def test_scalars_replaced_in_place() -> None:
    merged = merge_text(CASE1, FADE)
    assert merged == CASE1.replace("capacity_ah: 11 ", "capacity_ah: 10.4 ").replace(
        "fade_per_recharge: 0.002", "fade_per_recharge: 0.003")
    assert load_config(merged).battery.capacity_ah == Fraction(104, 10)


def test_missing_key_inserted_at_section_indent() -> None:
    text = "battery:\n    model: advanced  # four spaces\nstrategy:\n    safe_t: 0.25\n"
    merged = merge_text(text, FADE)
    assert merged == ("battery:\n    model: advanced  # four spaces\n    capacity_ah: 10.4\n"
                      "    fade_per_recharge: 0.003\nstrategy:\n    safe_t: 0.25\n")


def test_missing_section_appended() -> None:
    text = "# only a strategy\nstrategy:\n  safe_t: 0.25  # keep me\n"
    merged = merge_text(text, FADE)
    assert merged.startswith(text)
    assert yaml.safe_load(merged)["battery"] == {"capacity_ah": 10.4, "fade_per_recharge": 0.003}


def test_empty_and_comment_only_files() -> None:
    assert merge_text("", FADE) == "battery:\n  capacity_ah: 10.4\n  fade_per_recharge: 0.003\n"
    merged = merge_text("# nothing yet", FADE)
    assert merged.startswith("# nothing yet\nbattery:\n")


def test_flow_section() -> None:
    merged = merge_text("battery: {model: advanced, capacity_ah: 11}  # flow\n", FADE)
    assert merged.endswith("  # flow\n")
    assert yaml.safe_load(merged)["battery"] == {
        "model": "advanced", "capacity_ah": 10.4, "fade_per_recharge": 0.003}


def test_block_section_replaced_other_comments_kept() -> None:
    text = ("battery:\n  consumption:   # Table 2\n    high_wind_factor: 2\n"
            "  capacity_ah: 11  # keep\n# tail comment\n")
    value = {"energy_wh": Fraction(180), "voltages_v": {"low": Fraction(20), "medium":
             Fraction(22), "high": Fraction(25)}}
    merged = merge_text(text, {"battery.consumption": value})
    assert merged == ("battery:\n  consumption:   # Table 2\n    energy_wh: 180\n"
                      "    voltages_v:\n      low: 20\n      medium: 22\n      high: 25\n"
                      "  capacity_ah: 11  # keep\n# tail comment\n")


def test_nested_threshold_keys_created() -> None:
    merged = merge_text(CASE1, {"battery.voltage_thresholds.high": Fraction(8, 10),
                                "battery.voltage_thresholds.low": Fraction(15, 100)})
    assert "# fade: from the cycler" in merged and "# BS1" in merged
    thresholds = load_config(merged).battery.voltage_thresholds
    assert (thresholds.high, thresholds.low) == (Fraction(4, 5), Fraction(3, 20))


def test_empty_value_filled() -> None:
    merged = merge_text("battery:\n  capacity_ah:\n  model: advanced\n", FADE)
    assert yaml.safe_load(merged)["battery"]["capacity_ah"] == 10.4


def test_idempotent() -> None:
    once = merge_text(CASE1, FADE)
    assert merge_text(once, FADE) == once


MISSION = """\
battery:
  capacity_ah: 11          # new pack, as specified
  fade_per_recharge: 0.002 # BA1 (0.2 % per recharge)
  max_recharges: 50        # 50 flights a month
"""


def test_a_replaced_values_comment_with_a_number_says_where_the_value_came_from() -> None:
    """'fade_per_recharge: 0.000145 # BA1 (0.2 % per recharge)' was left: a comment that
    states the old value misleads. Comments without a number, and those of values left as
    they were, stay."""
    updates = {"battery.capacity_ah": Fraction(95, 10),
               "battery.fade_per_recharge": Fraction(145, 1000000),
               "battery.max_recharges": 50}
    note = "fitted by veribattery phm fade from cycles.csv"
    assert merge_text(MISSION, updates, note=note) == MISSION.replace(
        "capacity_ah: 11 ", "capacity_ah: 9.5 ").replace(
        "fade_per_recharge: 0.002 # BA1 (0.2 % per recharge)",
        "fade_per_recharge: 0.000145 # fitted by veribattery phm fade from cycles.csv")
    assert merge_text(MISSION, updates) == MISSION.replace(
        "capacity_ah: 11 ", "capacity_ah: 9.5 ").replace(
        "fade_per_recharge: 0.002 # BA1 (0.2 % per recharge)", "fade_per_recharge: 0.000145")


def test_not_a_mapping() -> None:
    with pytest.raises(PhmDataError, match=r"m\.yaml: a config must be a mapping"):
        merge_text("- a\n- b\n", FADE, "m.yaml")


def test_write_atomic_keeps_mode(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text("old\n")
    os.chmod(path, 0o640)
    write_atomic(path, "new\n")
    assert path.read_text() == "new\n"
    assert path.stat().st_mode & 0o777 == 0o640
    assert [p.name for p in tmp_path.iterdir()] == ["m.yaml"]
