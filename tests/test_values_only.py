"""Sweep points build only the reward structures their properties use (``rewards="named"``)."""

from __future__ import annotations

import json
from fractions import Fraction

import pytest

from tests.checker.test_conditional import SMALL_MISSION
from veribattery.config import load_config
from veribattery.config.schema import PAPER_PROPERTIES
from veribattery.errors import ModelError
from veribattery.lang import parse_model, parse_properties
from veribattery.lang.nodes import Model, PropertiesFile
from veribattery.mission import MissionSession, check_mission
from veribattery.pipeline import Session, check_model

PROPS = 'P=? [ F "success" ];\nR{"mt"}=? [ F "done" ]'


def _model_and_props() -> tuple[Model, PropertiesFile]:
    from veribattery.render import render_model

    cfg = load_config("{}\n", SMALL_MISSION)
    return parse_model(render_model(cfg)), parse_properties(PROPS)


def test_unused_reward_structures_are_not_built_and_values_stay() -> None:
    model, props = _model_and_props()
    full = check_model(model, props.properties)
    lean = Session(reuse=False, rewards="named").check(model, props.properties)
    assert [r.name for r in full.dtmc.rewards] == ["mt", "rc"]
    assert [r.name for r in lean.dtmc.rewards] == ["mt"]
    assert [r.value for r in lean.results] == [r.value for r in full.results]


def test_a_reward_by_index_keeps_every_structure() -> None:
    model, _ = _model_and_props()
    props = parse_properties('R{2}=? [ F "done" ];\nR=? [ F "done" ]')
    lean = Session(reuse=False, rewards="named").check(model, props.properties)
    assert [r.name for r in lean.dtmc.rewards] == ["mt", "rc"]


def test_sweep_checker_gives_the_values_of_check_mission() -> None:
    sets = (*SMALL_MISSION, "properties=" + json.dumps(
        {"p_success": PAPER_PROPERTIES["p_success"]}))
    cfg = load_config("{}\n", sets)
    lean = MissionSession.for_sweep(lump=True).check(cfg)
    full = check_mission(cfg)
    assert lean.values == full.values
    assert lean.recharge_cap_probability == full.recharge_cap_probability
    assert lean.run.dtmc.rewards == () and len(full.run.dtmc.rewards) == 2


def test_a_reward_by_index_empties_the_others_in_place() -> None:
    model, _ = _model_and_props()
    props = parse_properties('R{2}=? [ F "done" ]')
    full = check_model(model, props.properties)
    lean = Session(reuse=False, rewards="named").check(model, props.properties)
    assert [r.name for r in lean.dtmc.rewards] == ["mt", "rc"]  # R{2} still names "rc"
    mt, rc = lean.dtmc.rewards
    assert not mt.state.any() and not mt.transition.any()  # "mt" was not evaluated
    assert full.dtmc.rewards[0].transition.any()
    assert (rc.transition == full.dtmc.rewards[1].transition).all()
    assert [r.value for r in lean.results] == [r.value for r in full.results]


_TWO_REWARDS = """{kind}
module m
  s : [0..2] init 0;
  [a] s=0 -> 1/3:(s'=1) + 2/3:(s'=2);
  [b] s=0 -> (s'=1);
  [] s>0 -> true;
endmodule
rewards "used" s=0 : 1/3; endrewards
rewards "broken" mod(s, s-s)=0 : 1; endrewards
"""


@pytest.mark.parametrize(("kind", "prop", "value"), [
    ("dtmc", 'R{"used"}=? [ C<=2 ]', Fraction(1, 3)),
    ("mdp", 'R{"used"}max=? [ C<=2 ]', Fraction(1, 3)),
])
def test_exact_builds_only_the_rewards_it_reads_too(kind: str, prop: str,
                                                   value: Fraction) -> None:
    """--exact, as the float check of ``veribattery prism``, leaves the structures no
    property reads unbuilt: an unread "broken" one (a mod by 0 in every state) is no
    error, and a property that reads it still is."""
    from veribattery.pipeline import check_prism_file

    model = _TWO_REWARDS.format(kind=kind)
    run = check_prism_file(model, props_source=prop, exact=True, rewards="named")
    assert run.results[0].exact == value  # type: ignore[attr-defined]
    built = run.mdp if kind == "mdp" else run.dtmc  # type: ignore[union-attr]
    assert [r.name for r in built.rewards] == ["used"]
    with pytest.raises(ModelError, match="modulo with non-positive divisor"):
        check_prism_file(model, props_source=prop, exact=True, rewards="all")
    with pytest.raises(ModelError, match="modulo with non-positive divisor"):
        check_prism_file(model, props_source=prop.replace("used", "broken"), exact=True,
                         rewards="named")
