"""The mission MDP of synthesis mode in Storm (model-spec.md, "Synthesis: the mission as
an MDP"): the rendered model is the spec's, state by state and choice by choice (against
an independent Python reading of the spec's tables, tests/render/spec_mdp.py); BS1's DTMC
is one of its strategies; and Storm's values keep the spec's inclusions."""

from __future__ import annotations

import json
from collections import Counter
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest

from veribattery.config import MissionConfig, load_config
from veribattery.mission import check_mission
from veribattery.render import render_model, render_synthesis_model

stormpy = pytest.importorskip("stormpy")

from tests.render.prism_ranges import range_violations  # noqa: E402
from tests.render.spec_mdp import SpecMission, State, max_success  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
CASE1 = REPO / "configs" / "paper" / "case1.yaml"

#: One cell of four turbines at the base: BS1 (safe_t 0.3) cannot even take off at 5 Ah.
TINY = ("farm.cols=2", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=5",
        "battery.max_recharges=3")
#: Two cells (4 and 2 turbines, the second one cell away), a gusty wind.
SMALL = ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=6",
         "battery.max_recharges=8", "environment.p_wsp_c=0.3")

#: name: (overrides, (states, choices, transitions) as Storm builds them and as the
#: reference counts them). Variants cover the voltage levels, the wind's extremes, a
#: fixed level, another base, and a route by columns with Eq. 2's costs.
SMALL_CASES: dict[str, tuple[tuple[str, ...], tuple[int, int, int]]] = {
    "tiny": (TINY, (233, 373, 712)),
    "small": (SMALL, (1431, 2190, 4208)),
    "small-calm": ((*SMALL, "environment.p_wsp_c=0"), (401, 731, 731)),
    "small-flipping": ((*SMALL, "environment.p_wsp_c=1"), (479, 809, 809)),
    "small-basic-low": ((*SMALL, "battery.model=basic_low"), (915, 1443, 2786)),
    "three-by-three": (("farm.cols=3", "farm.rows=3", "farm.base=[1,1]",
                        "battery.capacity_ah=6", "battery.max_recharges=12"), (3927, 6022, 11722)),
    "columns-eq2": (("farm.cols=4", "farm.rows=2", "farm.base=[1,0]", "farm.route=snake_columns",
                     "battery.capacity_ah=6", "battery.max_recharges=6",
                     "battery.consumption={energy_wh: 180}"), (1045, 1625, 3164)),
}


def _cfg(overrides: tuple[str, ...], text: str = "") -> MissionConfig:
    return load_config(text, overrides)


def _build(text: str, tmp_path: Path, name: str = "model.prism") -> Any:
    """Storm's full model of *text* (no property: nothing is cut short), with state
    valuations and choice labels."""
    path = tmp_path / name
    path.write_text(text)
    options = stormpy.BuilderOptions()
    options.set_build_state_valuations()
    options.set_build_choice_labels()
    options.set_build_all_labels()
    options.set_build_all_reward_models()
    return stormpy.build_model(stormpy.parse_prism_program(str(path)), options=options)


def _valuation(model: Any, state: int) -> State:
    values = json.loads(str(model.state_valuations.to_json(state)))
    # A wind that never changes (p_wsp_c = 0) is a constant to Storm: no longer a variable.
    values.setdefault("wsp", 0)
    return State(*(int(values[v]) for v in State._fields))


def _choices(model: Any) -> dict[State, list[tuple[str, dict[State, float]]]]:
    """Per state valuation: each choice's label ("" if none) and successor distribution."""
    matrix, labels = model.transition_matrix, model.choice_labeling
    names = [_valuation(model, s) for s in range(model.nr_states)]
    out = {}
    for s in range(model.nr_states):
        rows = range(matrix.get_row_group_start(s), matrix.get_row_group_end(s))
        out[names[s]] = [
            ("".join(sorted(labels.get_labels_of_choice(r))),
             {names[e.column]: float(e.value) for e in matrix.get_row(r)})
            for r in rows
        ]
    return out


def _value(model: Any, formula: str, prism: Path) -> float:
    program = stormpy.parse_prism_program(str(prism))
    prop = stormpy.parse_properties(formula, program)[0]
    return float(stormpy.model_checking(model, prop).get_value(model.initial_states[0]))


def _same(storm: list[tuple[str, dict[State, float]]],
          spec: list[tuple[str, dict[State, Fraction]]]) -> bool:
    """The same choices (order aside), probabilities equal to float precision."""
    def key(choice: tuple[str, dict[State, Any]]) -> tuple[str, tuple[tuple[State, float], ...]]:
        return choice[0], tuple(sorted((y, round(float(p), 12)) for y, p in choice[1].items()))
    return Counter(map(key, storm)) == Counter(map(key, spec))


@pytest.mark.parametrize("name", list(SMALL_CASES))
def test_storm_builds_the_specs_mdp(name: str, tmp_path: Path) -> None:
    overrides, sizes = SMALL_CASES[name]
    cfg = _cfg(overrides)
    model = _build(render_synthesis_model(cfg), tmp_path)
    reference = SpecMission.of(cfg).reachable()
    storm = _choices(model)
    assert set(storm) == set(reference)
    assert [x for x in reference if not _same(storm[x], reference[x])] == []
    counted = (len(reference), sum(len(c) for c in reference.values()),
               sum(len(d) for c in reference.values() for _, d in c))
    assert (model.nr_states, model.nr_choices, model.nr_transitions) == counted == sizes
    assert str(model.model_type).endswith("MDP")


@pytest.mark.parametrize("name", ["tiny", "small", "three-by-three"])
def test_pmax_is_the_references(name: str, tmp_path: Path) -> None:
    cfg = _cfg(SMALL_CASES[name][0])
    prism = tmp_path / "model.prism"
    model = _build(render_synthesis_model(cfg), tmp_path)
    spec = SpecMission.of(cfg)
    expected = max_success(spec.reachable())[spec.initial]
    assert 0 < expected < 1
    pmax = _value(model, 'Pmax=? [ F "success" ]', prism)
    assert pmax == pytest.approx(float(expected), rel=1e-9)


def test_choice_table_by_hand(tmp_path: Path) -> None:
    """A few states of SMALL worked out from the spec's tables (C_NEW 60; cap(3..8) =
    floor(60 x 0.994..) = 59; route k=0 at the base with 4 turbines, k=1 one cell away
    with 2; the wind flips with probability 0.3)."""
    choices = _choices(_build(render_synthesis_model(_cfg(SMALL)), tmp_path))

    def labels(*x: int) -> list[str]:
        return sorted(label for label, _ in choices[State(*x)])

    assert labels(0, 0, 0, 60, 0, 0) == ["abort", "takeoff"]  # full battery, low wind
    # Back above the base, 4 units, SOC 4/59 low, high wind: landing costs 6 -- battery out.
    assert labels(4, 1, 0, 4, 3, 1) == ["abort"]
    # At cell k=1 with 14 units (SOC 14/59 < 0.25: low), low wind: inspecting costs 45,
    # flying back 1 x 5 -- so back or abort, and back lands at s=4 with 9 units.
    assert labels(2, 1, 0, 14, 3, 0) == ["abort", "back"]
    back = dict(choices[State(2, 1, 0, 14, 3, 0)])["back"]
    assert back == pytest.approx({State(4, 1, 0, 9, 3, 1): 0.3, State(4, 1, 0, 9, 3, 0): 0.7})
    abort = dict(choices[State(2, 1, 0, 14, 3, 0)])["abort"]
    assert abort == pytest.approx({State(6, 1, 0, 0, 3, 1): 0.3, State(6, 1, 0, 0, 3, 0): 0.7})
    # The last cell done (k = K-1 = 1, j = n = 2): no next, only backnext (8 of 16 units).
    assert labels(3, 1, 2, 16, 5, 1) == ["abort", "backnext"]
    by_kind = Counter((x.s, tuple(sorted(label for label, _ in c))) for x, c in choices.items())
    kinds = {s: {labels for (t, labels) in by_kind if t == s} for s in range(8)}
    assert kinds[5] == {("finish",), ("recharge",), ("oob",)}
    assert kinds[6] == kinds[7] == {("",)}
    assert all(c == [("", {x: 1.0})] for x, c in choices.items() if x.s >= 6)
    assert all(labels(*x) == ["wait"] for x in choices if x.s == 0 and x.wsp == 1)
    assert all(labels(*x) == ["finish"] for x in choices if x.s == 5 and x.k == 2)
    assert all(labels(*x) == ["oob"] for x in choices if x.s == 5 and x.k < 2 and x.rc == 8)
    assert all(("abort" in labels(*x)) == (1 <= x.s <= 4 or (x.s == 0 and x.wsp == 0))
               for x in choices)
    assert not any("next" in labels(*x) for x in choices if x.k == 1)


def _failure_as_abort(dist: dict[State, float]) -> dict[State, float]:
    """A distribution with every failure state's charge set to 0, as abort leaves it
    (BS1's `infeasible` leaves the charge as it was: docs/decisions.md)."""
    out: dict[State, float] = {}
    for y, p in dist.items():
        key = y._replace(b=0) if y.s == 6 else y
        out[key] = out.get(key, 0.0) + p
    return out


#: BS1's actions as choices of the MDP: a failure at s=0 (infeasible) or in flight
#: (oob for an action it cannot pay) is abort; oob at s=5 (the recharge cap) stays oob.
def _as_mdp_action(label: str, x: State) -> str:
    return "abort" if label == "infeasible" or (label == "oob" and x.s != 5) else label


@pytest.mark.parametrize("overrides", [
    SMALL, (*SMALL, "strategy.safe_t=0.1"), (*SMALL, "strategy.safe_t=0.05"),
    (*SMALL, "battery.model=basic_low", "strategy.safe_t=0.1"),
    (*SMALL, "environment.p_wsp_c=0.5", "strategy.safe_t=0.05"),
    (*SMALL, "environment.p_wsp_c=0", "strategy.safe_t=0.1"),
    ("farm.cols=3", "farm.rows=3", "farm.base=[1,1]", "battery.capacity_ah=8",
     "battery.max_recharges=12", "strategy.safe_t=0.2"),
], ids=["small", "safe-0.1", "safe-0.05", "basic-low", "windy", "calm", "three-by-three"])
def test_bs1_is_a_strategy_of_the_mdp(overrides: tuple[str, ...], tmp_path: Path) -> None:
    """Every BS1 state is a state of the MDP, and its one transition is one of the MDP's
    choices there, with the same action and successor distribution (failure states
    compared without their charge)."""
    cfg = _cfg(overrides)
    dtmc = _choices(_build(render_model(cfg), tmp_path, "bs1.prism"))
    mdp = _choices(_build(render_synthesis_model(cfg), tmp_path))
    assert State(0, 0, 0, SpecMission.of(cfg).c_new, 0, 0) in dtmc
    live = {x: c for x, c in dtmc.items() if x.s < 6}
    assert sum(1 for x in live if x.s in (1, 2, 3, 4)) > 20  # BS1 flies
    missing = []
    for x, ((label, dist),) in live.items():
        wanted = (_as_mdp_action(label, x), _failure_as_abort(dist))
        offered = [(a, _failure_as_abort(d)) for a, d in mdp.get(x, [])]
        if not any(a == wanted[0] and d == pytest.approx(wanted[1]) for a, d in offered):
            missing.append((x, wanted))
    assert missing == []



def _emit(tmp_path: Path, config: str | Path, *sets: str) -> tuple[Any, list[Any], str]:
    """``veribattery emit`` in synthesis mode; Storm's full model of the emitted MDP and
    its emitted properties, and the command's warnings."""
    from click.testing import CliRunner

    from veribattery.cli import cli

    out = tmp_path / "out"
    args = ["emit", str(config), "-o", str(out), "--set", "strategy.mode=synthesize"]
    result = CliRunner().invoke(cli, [*args, *(a for s in sets for a in ("--set", s))])
    assert result.exit_code == 0, result.output
    model = _build((out / "model.prism").read_text(), tmp_path)
    program = stormpy.parse_prism_program(str(out / "model.prism"))
    return model, stormpy.parse_properties((out / "properties.props").read_text(), program), \
        result.stderr


def _check_all(model: Any, props: list[Any]) -> dict[str, Any]:
    """Name → Storm's value at the initial state (False for an unachievable multi)."""
    init = model.initial_states[0]
    values = {}
    for prop in props:
        result = stormpy.model_checking(model, prop)
        values[prop.get_name()] = (bool(result.get_truth_values_vector()[init])
                                   if result.is_qualitative()
                                   else result.get_value(init))
    return values


def test_emitted_questions_in_storm(tmp_path: Path) -> None:
    """SMALL: BS1 succeeds with 0.2346, the best policy with 0.4330. The fastest policy
    as safe as BS1 is no slower; one safer than BS1 exists up to Pmax, none above."""
    bs1 = check_mission(_cfg(SMALL)).values
    assert bs1["p_success"] == pytest.approx(0.23461751381263, rel=1e-12)
    cfg_reqs = ["p_success >= 0.2", f"p_success >= {bs1['p_success']:.12f}",
                "p_success >= 0.43", "p_success >= 0.5", "exp_mission_time < 900"]
    model, props, warnings = _emit(tmp_path, REPO / "configs" / "example.yaml",
                                   *SMALL, f"requirements={json.dumps(cfg_reqs)}")
    assert "requirement 'exp_mission_time < 900' asks the MDP nothing" in warnings
    values = _check_all(model, props)
    assert list(values) == ["p_success_max", "exp_mission_time_max", "exp_recharges_max",
                            "fastest_1", "fastest_2", "fastest_3", "fastest_4"]
    spec = SpecMission.of(_cfg(SMALL))
    pmax = float(max_success(spec.reachable())[spec.initial])
    assert values["p_success_max"] == pytest.approx(pmax, rel=1e-9)
    assert bs1["p_success"] < 0.43 < pmax < 0.5
    # Multi-objective answers are approximate (Storm's default precision, 1e-4 relative).
    assert values["fastest_1"] < values["fastest_2"] <= bs1["exp_mission_time"] * (1 + 1e-4)
    assert values["fastest_2"] < values["fastest_3"] <= values["exp_mission_time_max"]
    assert values["fastest_4"] is False
    assert bs1["exp_mission_time"] <= values["exp_mission_time_max"]
    assert bs1["exp_recharges"] <= values["exp_recharges_max"] == pytest.approx(8)


@pytest.mark.parametrize("overrides", [
    SMALL, (*SMALL, "battery.model=basic_low"), (*SMALL, "strategy.safe_t=0.1"),
    SMALL_CASES["three-by-three"][0],
], ids=["small", "basic-low", "safe-0.1", "three-by-three"])
def test_bs1_at_most_pmax(overrides: tuple[str, ...], tmp_path: Path) -> None:
    """model-spec.md: P_BS1 <= Pmax (veribattery's check of the DTMC, Storm's of the MDP)."""
    cfg = _cfg(overrides)
    bs1 = check_mission(cfg).values["p_success"]
    model = _build(render_synthesis_model(cfg), tmp_path)
    pmax = _value(model, 'Pmax=? [ F "success" ]', tmp_path / "model.prism")
    assert isinstance(bs1, float)
    assert bs1 <= pmax


#: The paper's farm at 11 Ah (Table 3, case 1), and inside the dip of Fig. 6 (12.8 Ah):
#: (states, choices, transitions) of the MDP, Storm's Pmax, BS1's P(success).
PAPER_MDPS = {
    "case1": ((), (622845, 951108, 1877222), 1.0, 1.0),
    "dip-12.8Ah": (("battery.capacity_ah=12.8",), (817731, 1265743, 2505040), 1.0,
                   0.9390126540092353),
}


@pytest.mark.parametrize("name", list(PAPER_MDPS))
def test_paper_farm_mdp(name: str, tmp_path: Path) -> None:
    overrides, sizes, pmax, p_bs1 = PAPER_MDPS[name]
    cfg = load_config(CASE1, overrides)
    bs1 = check_mission(cfg).values["p_success"]
    assert bs1 == pytest.approx(p_bs1, rel=1e-9)
    model, props, _ = _emit(tmp_path, CASE1, *overrides)
    assert (model.nr_states, model.nr_choices, model.nr_transitions) == sizes
    value = float(stormpy.model_checking(model, props[0]).get_value(model.initial_states[0]))
    assert props[0].get_name() == "p_success_max"
    assert value == pytest.approx(pmax, rel=1e-9)
    assert bs1 <= value + 1e-12


def test_every_mdp_command_keeps_its_updates_in_range(tmp_path: Path) -> None:
    """PRISM's symbolic engines check each command over the whole domain (model-spec.md,
    "PRISM compatibility"); abort's own guard must keep (b'=0) and (s'=6) in range too."""
    tiny = ("farm.cols=2", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=3",
            "battery.resolution_ah=0.5", "battery.max_recharges=1",
            "battery.fade_per_recharge=0.1")
    text = render_synthesis_model(load_config("", tiny))
    assert range_violations(text, tmp_path) == set()
    broken = text.replace("[recharge] rc<RC_MAX  ->", "[recharge] true ->")
    assert range_violations(broken, tmp_path) == {("Battery", "rc")}
