"""A config's YAML floats keep the decimal they were written as."""

from __future__ import annotations

from fractions import Fraction

import pytest
import yaml

from veribattery.config import load_config
from veribattery.config.source import WrittenFloat, compose, construct


def _value(text: str) -> object:
    return construct(compose(text, "c.yaml"), text, "c.yaml")


@pytest.mark.parametrize(("written", "double", "kept"), [
    ("0.1000000000000000000001", 0.1, "0.1000000000000000000001"),  # 0.1's nearest double
    ("1.0e-330", 0.0, "1.0e-330"),  # below the subnormals
    ("1_000.5", 1000.5, "1000.5"),  # YAML 1.1's separators dropped, as PyYAML does
])
def test_a_float_is_its_double_and_its_text(written: str, double: float, kept: str) -> None:
    value = _value(f"x: {written}")["x"]  # type: ignore[index]
    assert isinstance(value, WrittenFloat)
    assert value == double
    assert value.text == kept


def test_infinity_and_nan_stay_plain_floats() -> None:
    values = _value("[.inf, -.inf, .nan]")
    assert [type(v) for v in values] == [float, float, float]  # type: ignore[union-attr]


def test_an_exact_value_reads_the_text() -> None:
    cfg = load_config("strategy: {safe_t: 0.25}\nbattery: {capacity_ah: 11.0}\n")
    assert cfg.strategy.safe_t == Fraction(1, 4)
    assert cfg.battery.capacity_ah == 11


def test_a_config_written_back_keeps_the_text() -> None:
    assert yaml.safe_dump(_value("x: 0.1000000000000000000001")) == \
        "x: 0.1000000000000000000001\n"
