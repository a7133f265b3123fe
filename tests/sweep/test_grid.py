"""Grids from --vary specs: exact decimal ranges, YAML lists, one-line errors."""

from __future__ import annotations

import pytest

from veribattery.errors import ConfigError
from veribattery.sweep import Axis, grid, parse_axis, point_values


def test_range_is_exact_and_includes_stop() -> None:
    axis = parse_axis("battery.capacity_ah=10:13:0.2")
    assert axis.key == "battery.capacity_ah"
    assert len(axis.values) == 16
    assert [repr(v) for v in axis.values[:3]] == ["10", "10.2", "10.4"]
    assert axis.values[-1] == 13 and isinstance(axis.values[-1], int)
    assert point_values({"battery.capacity_ah": axis.values[7]}) == {"battery.capacity_ah": 11.4}


@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        ("strategy.safe_t=0.1:0.3:0.1", (0.1, 0.2, 0.3)),  # 0.1+0.1+0.1 != 0.3 in floats
        ("battery.capacity_ah=10:13:0.5", (10, 10.5, 11, 11.5, 12, 12.5, 13)),
        ("battery.capacity_ah=10:11.9:0.5", (10, 10.5, 11, 11.5)),  # stop off the grid
        ("battery.capacity_ah=11:11:1", (11,)),
        ("environment.p_wsp_c=0:1e-1:0.05", (0, 0.05, 0.1)),
        ("battery.model=advanced,basic_high", ("advanced", "basic_high")),
        ("strategy.safe_t=0.25, 0.3", (0.25, 0.3)),
        ("farm.base=[0,0],[1,1]", ((0, 0), (1, 1))),
        ("strategy.safe_t=0.25", (0.25,)),
    ],
    ids=lambda v: v if isinstance(v, str) else "",
)
def test_axis_values(spec: str, expected: tuple[object, ...]) -> None:
    assert parse_axis(spec).values == expected


def test_point_values_are_what_yaml_loads() -> None:
    axis = parse_axis("farm.base=[0,0],[1,1]")
    values = point_values({axis.key: axis.values[1]})
    assert values == {"farm.base": [1, 1]} and isinstance(values["farm.base"], list)
    assert point_values({"battery.model": "basic_high"}) == {"battery.model": "basic_high"}


def test_grid_is_the_product_first_axis_slowest() -> None:
    axes = [Axis("a", (1, 2)), Axis("b", ("x", "y", "z"))]
    points = grid(axes)
    assert len(points) == 6
    assert points[:4] == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"}, {"a": 1, "b": "z"},
                          {"a": 2, "b": "x"}]
    assert grid([]) == [{}]


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("battery.capacity_ah", "expected KEY=START:STOP:STEP or KEY=a,b,c"),
        ("battery.capacity_ah=", "expected KEY=START:STOP:STEP"),
        ("battery.capacty_ah=10:12:1", "did you mean 'battery.capacity_ah'?"),
        ("battery.capacity_ah=10:12", "must be START:STOP:STEP"),
        ("battery.capacity_ah=10:12:1:1", "must be START:STOP:STEP"),
        ("battery.capacity_ah=10:12:0", "STEP must be > 0"),
        ("battery.capacity_ah=10:12:-1", "STEP must be > 0"),
        ("battery.capacity_ah=12:10:1", "STOP must be ≥ START"),
        ("battery.capacity_ah=ten:12:1", "'ten' is not a decimal number"),
        ("battery.capacity_ah=nan:12:1", "'nan' is not a decimal number"),
        ("battery.capacity_ah=1:1000:0.01", "at most 10,000"),
        ("farm.base=[0,", "is not START:STOP:STEP or a comma list"),
        ("battery.model=a,,b", "is not START:STOP:STEP or a comma list"),
        ("battery.max_recharges=10,10", "10 is given twice (each point runs once)"),
        ("farm.base=[0,0],[1,1],[0,0]", "[0, 0] is given twice"),
        # 10^5000 was a traceback, 10^99999999 minutes of CPU; a count of 401 digits noise
        ("farm.cols=2:3:1e-5000", "1e-5000 is out of range: a number must be 0 or between "
         "1e-400 and 1e400 in size, with at most 400 significant digits"),
        ("farm.cols=2:1e99999999:1", "1e99999999 is out of range"),
        ("farm.cols=2:3:1e-400", "range gives about 10^400 values (at most 10,000)"),
        (f"farm.cols=2,{'9' * 500}", "999999999999\u2026999999 (500 characters) is out of "
         "range"),
        ('properties.1bad=P=? [ F "success" ]', "property name '1bad' must be an identifier"),
    ],
)
def test_bad_specs_name_the_option(spec: str, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_axis(spec)
    text = str(info.value)
    assert text.startswith(f"--vary {spec!r}: ")
    assert message in text
    assert "\n" not in text


def test_grid_rejects_a_key_varied_twice_and_huge_grids() -> None:
    with pytest.raises(ConfigError, match="varied more than once"):
        grid([Axis("a", (1,)), Axis("a", (2,))])
    with pytest.raises(ConfigError, match="at most 10,000"):
        grid([Axis("a", tuple(range(200))), Axis("b", tuple(range(200)))])


def test_a_list_reads_numbers_as_a_config_does() -> None:
    """Numbers as in a config file: not octal ``010``, not base-60 ``1:05`` (text instead)."""
    assert parse_axis("battery.max_recharges=12,0x0c0,1_3").values == (12, 192, 13)
    assert parse_axis("battery.max_recharges=010,1:05").values == ("010", "1:05")
