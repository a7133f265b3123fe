"""The rendered models in Storm: exact sizes and values for the paper's configs, the
calibration of model-spec.md, one action per state, and PRISM's domain-wide range check."""

from __future__ import annotations

import collections
from pathlib import Path
from typing import Any

import pytest

from veribattery.config import load_config
from veribattery.render import render_model, render_properties

stormpy = pytest.importorskip("stormpy")

from tests.render.prism_ranges import range_violations  # noqa: E402

REPO = Path(__file__).resolve().parents[2]

# config: (states, transitions, P[F success], R{mt}[F done], R{rc}[F done]), measured with Storm
PAPER_RESULTS = {
    "case1": (176481, 350504, 1.0, 4796.963222950834, 42.771339379900304),
    "case2": (183789, 364886, 1.0, 4344.428424241644, 37.98402828581247),
    "case3": (176481, 350504, 0.9998202187217463, 7616.988913506162, 72.43001143348013),
    "case4": (183789, 364886, 0.9999876910894963, 6477.594848366805, 60.320963721068836),
    "basic_high": (193787, 386126, 1.0, 4189.305187276084, 36.33511267131847),
    "basic_medium": (180495, 359590, 1.0, 4858.888888888912, 43.44444444444459),
    "basic_low": (178357, 354516, 0.6561000000000003, 3952.4102358024875, 35.29012345679025),
}


def _program(text: str, tmp_path: Path) -> Any:
    path = tmp_path / "model.prism"
    path.write_text(text)
    return stormpy.parse_prism_program(str(path))


def _check(
    config: str | Path, tmp_path: Path, overrides: tuple[str, ...] = ()
) -> tuple[Any, list[float]]:
    cfg = load_config(config, overrides)
    program = _program(render_model(cfg), tmp_path)
    props = stormpy.parse_properties(render_properties(cfg), program)
    model = stormpy.build_model(program, props)
    init = model.initial_states[0]
    return model, [stormpy.model_checking(model, p).get_value(init) for p in props]


@pytest.mark.parametrize("name", list(PAPER_RESULTS))
def test_paper_config_in_storm(name: str, tmp_path: Path) -> None:
    states, transitions, *expected = PAPER_RESULTS[name]
    model, values = _check(REPO / "configs" / "paper" / f"{name}.yaml", tmp_path)
    assert (model.nr_states, model.nr_transitions) == (states, transitions)
    # The paper's three properties come first (the conditional defaults follow).
    assert values[:len(expected)] == pytest.approx(expected, rel=1e-6)


def test_calibration_against_the_paper(tmp_path: Path) -> None:
    """model-spec.md: about 42.7 expected recharges at baseline, about 72.4 in case 3."""
    _, case1 = _check(REPO / "configs" / "paper" / "case1.yaml", tmp_path)
    _, case3 = _check(REPO / "configs" / "paper" / "case3.yaml", tmp_path)
    assert case1[2] == pytest.approx(42.7, abs=0.1)  # paper: 42.65
    assert case3[2] == pytest.approx(72.4, abs=0.1)  # paper: 72.16


def test_advanced_model_dips_between_12_and_13_ah(tmp_path: Path) -> None:
    """Fig. 6: P(success) is 1 at 12 Ah, drops inside 12-13 Ah (e.g. 12.8 Ah), recovers after."""
    p = {
        cap: _check("", tmp_path, (f"battery.capacity_ah={cap}",))[1][0]
        for cap in ("12", "12.8", "13.2")
    }
    assert p["12"] == pytest.approx(1.0)
    assert p["12.8"] == pytest.approx(0.939013, abs=1e-6)
    assert p["13.2"] == pytest.approx(1.0)


def test_one_action_in_every_live_state(tmp_path: Path) -> None:
    cfg = load_config(REPO / "configs" / "paper" / "case4.yaml")
    program = _program(render_model(cfg), tmp_path)
    model = stormpy.build_model(program, options=stormpy.BuilderOptions(build_full=True))
    labels = model.choice_labeling
    counts = collections.Counter(
        len(labels.get_labels_of_choice(s)) for s in range(model.nr_states)
    )
    done = model.labeling.get_states("done")
    assert counts[1] == model.nr_states - done.get_number_of_set_bits()
    assert counts[0] == done.get_number_of_set_bits()  # the absorbing loop is unlabelled


def test_every_command_keeps_its_updates_in_range(tmp_path: Path) -> None:
    tiny = (
        "farm.cols=2",
        "farm.rows=2",
        "farm.base=[0,0]",
        "battery.capacity_ah=3",
        "battery.resolution_ah=0.5",
        "battery.max_recharges=1",
        "battery.fade_per_recharge=0.1",
    )
    text = render_model(load_config("", tiny))
    assert range_violations(text, tmp_path) == set()
    broken = text.replace("[inspect]  b>=c_ins   ->", "[inspect]  true ->")
    assert range_violations(broken, tmp_path) == {("Battery", "b")}
