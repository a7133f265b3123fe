"""Pmax of success over a sweep's points (``reproduce fig6 --optimal``): one MDP per
distinct model, each point's value at least BS1's at the same battery and wind, and
Storm's Pmax on the emitted MDP."""

from __future__ import annotations

from pathlib import Path

import pytest

from veribattery.config import MissionConfig, load_config
from veribattery.mission import check_mission
from veribattery.render import render_synthesis_model
from veribattery.synthesis.model import Certified
from veribattery.synthesis.sweep_pmax import pmax_of_configs

#: Two cells (4 and 2 turbines, the second one cell away): BS1 flies nothing at 4 Ah
#: and loses missions at 5-6 Ah that a better return policy saves.
SMALL = ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.max_recharges=8")
CAPACITIES = (4.0, 5.0, 6.0)
#: Fig. 6's cases as they differ on the small farm: BS1's safe_t, and the wind.
CASES = (("0.3", "0.3"), ("0.1", "0.3"), ("0.3", "0.1"))


def _cfg(capacity: float, safe_t: str, wind: str) -> MissionConfig:
    return load_config("", (*SMALL, f"battery.capacity_ah={capacity!r}",
                            f"strategy.safe_t={safe_t}", f"environment.p_wsp_c={wind}"))


@pytest.fixture(scope="module")
def swept() -> tuple[list[MissionConfig], list[Certified], list[tuple[int, int]]]:
    cfgs = [_cfg(c, s, w) for c in CAPACITIES for s, w in CASES]
    told: list[tuple[int, int]] = []
    values = pmax_of_configs(cfgs, progress=lambda done, total: told.append((done, total)))
    return cfgs, values, told


def test_one_mdp_per_capacity_and_wind(
        swept: tuple[list[MissionConfig], list[Certified], list[tuple[int, int]]]) -> None:
    cfgs, values, told = swept
    # safe_t does not change the MDP: 3 capacities x 2 winds, not x 3 cases
    assert told == [(i, 6) for i in range(1, 7)]
    by_point = dict(zip(((c.battery.capacity_ah, c.environment.p_wsp_c) for c in cfgs),
                        values, strict=True))
    assert len(by_point) == 6
    for cfg, value in zip(cfgs, values, strict=True):
        assert value == by_point[cfg.battery.capacity_ah, cfg.environment.p_wsp_c]


def test_pmax_is_at_least_each_bs1_case(
        swept: tuple[list[MissionConfig], list[Certified], list[tuple[int, int]]]) -> None:
    cfgs, values, _ = swept
    gains = []
    for cfg, value in zip(cfgs, values, strict=True):
        bs1 = check_mission(cfg).values["p_success"]
        assert isinstance(bs1, float)
        assert value.lower <= value.value <= value.upper
        assert bs1 <= value.upper
        gains.append(value.value - bs1)
    assert gains[0] == 0.0  # 4 Ah: nobody flies the mission
    # 5 Ah, gusty wind: BS1 at safe_t 0.3 never succeeds, the best policy does (0.0853)
    assert values[3].value == pytest.approx(0.08533337310730925, rel=1e-9)
    assert gains[3] == values[3].value
    assert max(gains) > 0.15  # 6 Ah: 0.4330 against BS1's 0.2346


def test_a_pool_gives_the_same_values(
        swept: tuple[list[MissionConfig], list[Certified], list[tuple[int, int]]]) -> None:
    cfgs, values, _ = swept
    assert pmax_of_configs(cfgs[-3:], jobs=2) == values[-3:]


def test_storm_agrees_on_an_emitted_mdp(
        swept: tuple[list[MissionConfig], list[Certified], list[tuple[int, int]]],
        tmp_path: Path) -> None:
    stormpy = pytest.importorskip("stormpy")
    cfgs, values, _ = swept
    path = tmp_path / "model.prism"
    path.write_text(render_synthesis_model(cfgs[-1]))  # 6 Ah, the calmer wind
    program = stormpy.parse_prism_program(str(path))
    prop = stormpy.parse_properties('Pmax=? [ F "success" ]', program)
    model = stormpy.build_model(program, prop)
    storm = float(stormpy.model_checking(model, prop[0]).get_value(model.initial_states[0]))
    assert 0 < storm < 1
    assert values[-1].value == pytest.approx(storm, rel=1e-9)
    assert values[-1].lower - 1e-12 <= storm <= values[-1].upper + 1e-12
