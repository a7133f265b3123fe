"""Sweep test helpers: a tiny mission (3x3 farm, 0.5 Ah units, 25 recharges, ~2,500 states)."""

from __future__ import annotations

import pandas as pd
from click.testing import CliRunner, Result

from veribattery.cli import cli
from veribattery.config.schema import PAPER_PROPERTIES
from veribattery.sweep import Axis, parse_axis

SMALL_FARM = ("farm.cols=3", "farm.rows=3", "farm.base=[0,0]", "battery.resolution_ah=0.5",
              "battery.max_recharges=25")

#: Rows per grid point: one per default property.
PER_POINT = len(PAPER_PROPERTIES)

#: ``--vary`` for two points: two capacities.
TWO_POINTS = ("--vary", "battery.capacity_ah=10:10.5:0.5")

#: Four points: two models x two capacities.
FOUR_POINTS = ("battery.model=advanced,basic_high", "battery.capacity_ah=10:10.5:0.5")


def run(*args: str) -> Result:
    """``veribattery ARGS`` through click's test runner."""
    return CliRunner().invoke(cli, list(args))


def four_axes() -> list[Axis]:
    return [parse_axis(spec) for spec in FOUR_POINTS]


def same_results(left: pd.DataFrame, right: pd.DataFrame) -> None:
    """Equal bit for bit in every column but the timings, and in the same (grid) order."""
    columns = [c for c in left.columns if c != "seconds"]
    assert list(left.columns) == list(right.columns)
    pd.testing.assert_frame_equal(
        left[columns].reset_index(drop=True), right[columns].reset_index(drop=True),
        check_exact=True, check_dtype=False,
    )
