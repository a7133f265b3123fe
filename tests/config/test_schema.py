"""Validation: defaults are the paper's, decimals are exact, every bad input names its key."""

from __future__ import annotations

import math
from fractions import Fraction

import pydantic
import pytest

from veribattery.config import (
    MissionConfig,
    known_keys,
    load_config,
    parse_requirement,
    requirement_problem,
)
from veribattery.errors import ConfigError


def test_empty_config_is_the_papers_baseline() -> None:
    cfg = load_config("")
    assert (cfg.farm.cols, cfg.farm.rows, cfg.farm.base, cfg.farm.route) == (
        6,
        6,
        (2, 2),
        "snake_rows",
    )
    assert cfg.battery.model == "advanced"
    assert cfg.battery.capacity_ah == 11
    assert cfg.battery.fade_per_recharge == Fraction(2, 1000)
    assert cfg.battery.max_recharges == 200
    assert cfg.strategy.safe_t == Fraction(3, 10)
    assert cfg.environment.p_wsp_c == Fraction(1, 10)
    assert cfg.times_min.recharge == 90 and cfg.times_min.wait == 0
    assert list(cfg.properties) == ["p_success", "exp_mission_time", "exp_recharges",
                                    "exp_mission_time_given_success", "exp_recharges_given_success"]
    assert cfg == MissionConfig()


def test_decimals_are_exact() -> None:
    cfg = load_config(
        "strategy: {safe_t: 0.3}\nbattery: {capacity_ah: 12.8, fade_per_recharge: 0.002}"
    )
    assert cfg.strategy.safe_t == Fraction(3, 10)  # not the binary float 0.299999...
    assert cfg.battery.capacity_ah == Fraction(64, 5)
    assert cfg.battery.fade_per_recharge == Fraction(1, 500)
    assert load_config("strategy: {safe_t: 1/3}").strategy.safe_t == Fraction(1, 3)


def test_basic_models_have_no_fade() -> None:
    assert load_config("battery: {model: basic_low}").battery.fade == 0
    assert load_config("").battery.fade == Fraction(1, 500)


def test_config_is_frozen() -> None:
    cfg = load_config("")
    with pytest.raises(pydantic.ValidationError):
        cfg.strategy.safe_t = Fraction(1, 2)  # type: ignore[misc]


BAD = [
    ("strategy: {safe_t: 1.5}", "strategy.safe_t: must be in (0, 1), got 1.5"),
    ("strategy: {safe_t: 0}", "strategy.safe_t: must be in (0, 1), got 0"),
    ("strategy: {safe_t: abc}", "strategy.safe_t: must be a number, got 'abc'"),
    ("environment: {p_wsp_c: 1.2}", "environment.p_wsp_c: must be in [0, 1], got 1.2"),
    ("environment: {p_wsp_c: -0.1}", "environment.p_wsp_c: must be in [0, 1], got -0.1"),
    ("battery: {capacity_ah: 0}", "battery.capacity_ah: must be > 0, got 0"),
    ("battery: {capacity_ah: -3}", "battery.capacity_ah: must be > 0, got -3"),
    ("battery: {resolution_ah: 0}", "battery.resolution_ah: must be > 0, got 0"),
    (
        "battery: {capacity_ah: 11.05}",
        "battery.capacity_ah: must be a whole number of resolution_ah (0.1) units, got 11.05",
    ),
    (
        "battery: {capacity: 11}",
        "battery.capacity: unknown key (did you mean 'battery.capacity_ah'?)",
    ),
    ("stratgy: {safe_t: 0.3}", "stratgy: unknown key (did you mean 'strategy'?)"),
    (
        "battery: {model: fancy}",
        "battery.model: must be one of 'advanced', 'basic_high', "
        "'basic_medium' or 'basic_low', got 'fancy'",
    ),
    ("battery: {fade_per_recharge: 1}", "battery.fade_per_recharge: must be in [0, 1), got 1"),
    ("battery: {max_recharges: -1}", "battery.max_recharges: must be >= 0, got -1"),
    ("battery: {max_recharges: 2.5}", "battery.max_recharges: must be an integer, got 2.5"),
    (
        "battery: {fade_per_recharge: 0.01, max_recharges: 100}",
        "battery.fade_per_recharge: fade_per_recharge x max_recharges must be < 1",
    ),
    (
        "battery: {voltage_thresholds: {low: 0.8}}",
        "battery.voltage_thresholds.low: must be <= high (0.75), got 0.8",
    ),
    (
        "battery: {voltage_thresholds: {high: 1}}",
        "battery.voltage_thresholds.high: must be in (0, 1), got 1",
    ),
    (
        "battery: {consumption: {cell: {low: 0}}}",
        "battery.consumption.cell.low: must be > 0, got 0",
    ),
    (
        "battery: {consumption: {cel: 1}}",
        "battery.consumption.cel: unknown key (did you mean 'battery.consumption.cell'?)",
    ),
    (
        "battery: {consumption: {energy_wh: 180, cell: {low: 1}}}",
        "battery.consumption.cell: cannot be mixed with the other form of battery.consumption",
    ),
    ("farm: {cols: six}", "farm.cols: must be an integer, got 'six'"),
    ("farm: {cols: 1}", "farm.cols: must be at least 2 turbines, got 1"),
    ("farm: {rows: 1}", "farm.rows: must be at least 2 turbines, got 1"),
    ("farm: 5", "farm: must be a mapping of keys, got 5"),
    (
        "farm: {base: [5, 2]}",
        "farm.base: cell [5, 2] is outside the 5 x 5 cells (x in 0..4, y in 0..4)",
    ),
    ("farm: {base: [1]}", "farm.base: must be a cell [x, y] of two integers, got [1]"),
    (
        "farm: {cols: 3, rows: 3, base: [0, 0], route: [[0, 0], [1, 0], [1, 1]]}",
        "farm.route: misses cell [0, 1] (1 missing)",
    ),
    (
        "farm: {cols: 3, rows: 3, base: [0, 0], route: [[0, 0], [1, 0], [1, 1], [1, 1]]}",
        "farm.route: cell [1, 1] appears twice",
    ),
    (
        "farm: {cols: 3, rows: 3, base: [0, 0], route: [[0, 0], [1, 0], [1, 1], [0, 2]]}",
        "farm.route: cell [0, 2] is outside the 2 x 2 cells",
    ),
    (
        "farm: {route: zigzag}",
        "farm.route: must be 'snake_rows', 'snake_columns' or a list of cells [x, y], got 'zigzag'",
    ),
    ("times_min: {recharge: -90}", "times_min.recharge: must be >= 0, got -90"),
    (
        "requirements: ['p_win >= 0.9']",
        "requirements[0]: unknown property 'p_win' (declared: p_success, exp_mission_time, "
        "exp_recharges, exp_mission_time_given_success, exp_recharges_given_success)",
    ),
    ("requirements: ['p_success about 1']", "requirements[0]: must look like 'p_success >= 0.99'"),
    (
        "properties: {'2x': 'P=? [ F \"done\" ]'}",
        "properties: property name must be an identifier, got '2x'",
    ),
    ("[1, 2]", "config: must be a mapping of keys, got list"),
]


@pytest.mark.parametrize(("text", "message"), BAD, ids=[m.split(":")[0] for _, m in BAD])
def test_bad_input_names_key_and_allowed_values(text: str, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        load_config(text)
    assert message in info.value.message
    assert "\n" not in str(info.value)


def test_several_problems_are_counted_on_one_line() -> None:
    with pytest.raises(ConfigError, match=r"\(and 1 more problem\(s\)\)$"):
        load_config("strategy: {safe_t: 2}\nenvironment: {p_wsp_c: 2}")


def test_requirements_parse() -> None:
    cfg = load_config("requirements: ['p_success >= 0.99', 'exp_recharges<50']")
    first, second = cfg.parsed_requirements
    assert (first.prop, first.op, first.bound) == ("p_success", ">=", Fraction(99, 100))
    assert (second.prop, second.op, second.bound) == ("exp_recharges", "<", 50)
    assert first.holds(1.0) and not first.holds(0.98)
    assert str(first) == "p_success >= 0.99"
    with pytest.raises(ValueError, match="bound must be a number"):
        parse_requirement("p_success >= lots")


def test_requirements_compare_exactly_with_their_rational_bound() -> None:
    huge = parse_requirement("exp_mission_time < 1e400")  # no double: float() overflows
    assert huge.holds(1.7976931348623157e308) and not huge.holds(math.inf)
    assert not parse_requirement("t <= 1e400").holds(math.inf)  # infinite, not 1e400
    third = parse_requirement("p >= 1/3")
    assert not third.holds(1 / 3)  # the double nearest 1/3 is below it
    assert third.holds(math.nextafter(1 / 3, 1.0))
    assert not third.holds(math.nan)


@pytest.mark.parametrize(("formula", "bound", "refused"), [
    ('P=? [ F "success" ]', "1.5", True),
    ('P=? [ F "success" ]', "-0.5", True),
    ('P=? [ F "success" ]', "1", False),  # P>=1 asks for certainty: a real requirement
    ('P=? [ F "success" ]', "0", False),
    ('  Pmax=?[ F "a" ]  ', "2", True),
    ('Pmin = ? [ "a" U "b" ]', "2", True),
    ('S=? [ "a" ]', "2", True),
    ('P=? [ F x=1 & y<"]" ]', "2", True),  # a bracket in quotes does not close the formula
    ('R{"mt"}=? [ F "done" ]', "500", False),  # minutes: any bound
    ('P=? [ F "a" ] * 100', "50", False),  # a percentage, not a probability
])
def test_a_probability_is_bounded_in_0_1(formula: str, bound: str, refused: bool) -> None:
    problem = requirement_problem(parse_requirement(f"p >= {bound}"), formula)
    assert (problem is not None) == refused
    if refused:
        assert problem == (f"p is a probability ({formula.strip()}): the bound must be in "
                           f"[0, 1], got {bound}")


@pytest.mark.parametrize(("properties", "refused"), [
    ({"p": '"q"', "q": 'P=? [ F "success" ]'}, True),  # a reference to a probability
    ({"p": '"r"', "r": '"q"', "q": 'P=? [ F "success" ]'}, True),  # through two
    ({"p": '"q"', "q": 'R{"mt"}=? [ F "done" ]'}, False),  # to a reward
    ({"p": '"q"', "q": '"p"'}, False),  # a cycle (refused elsewhere, not here)
    ({"p": '"success"'}, False),  # a label, not a property
])
def test_a_reference_to_a_probability_is_bounded_in_0_1(properties: dict[str, str],
                                                       refused: bool) -> None:
    problem = requirement_problem(parse_requirement("p >= 2"), properties["p"], properties)
    assert (problem is not None) == refused
    if refused:
        assert problem == (f"p is a probability ({properties['p']}, P=? [ F \"success\" ]): "
                           "the bound must be in [0, 1], got 2")


def test_a_config_requirement_follows_a_reference() -> None:
    with pytest.raises(ConfigError, match="again is a probability"):
        load_config("properties: {ok: 'P=? [ F \"success\" ]', again: '\"ok\"'}\n"
                    "requirements: ['again >= 1.5']")


def test_a_requirement_on_a_reward_may_exceed_1() -> None:
    cfg = load_config("requirements: ['exp_mission_time <= 500', 'p_success >= 1']")
    assert [str(r) for r in cfg.parsed_requirements] == ["exp_mission_time <= 500",
                                                          "p_success >= 1"]


def test_custom_properties_replace_the_papers() -> None:
    cfg = load_config(
        "properties: {p_fail: 'P=? [ F \"failure\" ]'}\nrequirements: ['p_fail < 0.01']"
    )
    assert list(cfg.properties) == ["p_fail"]


def test_known_keys_cover_both_consumption_forms() -> None:
    keys = known_keys()
    assert "battery.consumption.high_wind_factor" in keys
    assert "battery.consumption.energy_wh" in keys
    assert "farm.base" in keys and "times_min.wait" in keys
