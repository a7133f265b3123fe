"""A sweep point's config: the file read once, the point's values set on it and validated
once -- equal to what load_config makes of the file with the point's keys given by
``--set`` (the way every point was loaded before), errors and their places included."""

from __future__ import annotations

from pathlib import Path

import pytest

from veribattery.config import MissionConfig, config_to_yaml, load_config, read_config
from veribattery.errors import ConfigError
from veribattery.mission import validate_properties
from veribattery.render import render_model
from veribattery.sweep import parse_axis, point_values
from veribattery.sweep.grid import Point, yaml_text

CONFIG = """\
farm:
  cols: 4
  rows: 4
  base: [2, 2]
battery:
  model: basic_high
properties:
  p_success: 'P=? [ F "success" ]'
"""
SETS = ("battery.max_recharges=30",)


def _both(tmp_path: Path, point: Point) -> tuple[MissionConfig, MissionConfig]:
    """*point*'s config made once from the document, and by load_config with --set."""
    path = tmp_path / "mission.yaml"
    path.write_text(CONFIG)
    document = read_config(path, SETS)
    sets = [f"{key}={yaml_text(value)}" for key, value in point.items()]
    return (document.with_values(point_values(point)).validate(),
            load_config(path, [*SETS, *sets]))


@pytest.mark.parametrize("point", [
    {"battery.capacity_ah": parse_axis("battery.capacity_ah=10:11:0.1").values[3]},
    {"farm.base": parse_axis("farm.base=[0,0],[1,2]").values[1]},
    {"battery.model": "advanced", "strategy.safe_t": 0.25, "environment.p_wsp_c": 0.05},
    {"properties.extra": 'R{"mt"}=? [ F "done" ]'},
    {"requirements": ("p_success>=0.9",), "battery.fade_per_recharge": 0.001},
], ids=["range", "cell", "three-keys", "property", "list"])
def test_a_point_is_the_config_load_config_makes(tmp_path: Path, point: Point) -> None:
    ours, theirs = _both(tmp_path, point)
    assert ours == theirs
    assert config_to_yaml(ours) == config_to_yaml(theirs)
    assert render_model(ours) == render_model(theirs)


def _error(make: object) -> str:
    with pytest.raises(ConfigError) as info:
        make()  # type: ignore[operator]
    return str(info.value)


def test_errors_are_those_of_load_config(tmp_path: Path) -> None:
    """The same errors, but for the option: a point's key was given by no ``--set``."""
    path = tmp_path / "mission.yaml"
    path.write_text(CONFIG)
    document = read_config(path, SETS)
    for point in ({"strategy.safe_t": 1.5},  # at the varied key: no place in the file
                  {"farm.cols": 3}):  # farm.base, in the file, no longer inside: cols' fault
        sets = [f"{key}={yaml_text(value)}" for key, value in point.items()]
        ours = _error(lambda p=point: document.with_values(point_values(p)).validate())
        theirs = _error(lambda s=sets: load_config(path, [*SETS, *s]))
        assert theirs == f"--set {ours}"
    assert ours.startswith("farm.cols: 3 x 4 turbines leave farm.base's cell [2, 2] outside")


def test_a_bad_varied_formula_names_its_key(tmp_path: Path) -> None:
    ours, theirs = _both(tmp_path, {"properties.extra": 'P=? [ F "nosuch" ]'})
    message = _error(lambda: validate_properties(ours))
    assert message == _error(lambda: validate_properties(theirs))
    assert message.startswith("--set properties.extra: ")
