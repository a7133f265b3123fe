"""Pmax on a mission MDP whose optimum ties many rows with other distributions: the
upper side of the certificate needs the tied rows' margin solved to its optimum (two
rounds of policy iteration left it short, and the upper bound fell to the trivial 1)."""

from __future__ import annotations

from pathlib import Path

import pytest

from veribattery.analyses.figures import CAPACITY_SETS
from veribattery.config import load_config
from veribattery.render import render_synthesis_model
from veribattery.synthesis.sweep_pmax import pmax_of_model

#: Fig. 6's basic_high battery at 6.6 Ah (409,629 states): BS1 never succeeds.
POINT = (*CAPACITY_SETS, "battery.model=basic_high", "battery.capacity_ah=6.6")


def test_the_upper_bound_is_certified_tightly(tmp_path: Path) -> None:
    text = render_synthesis_model(load_config("", POINT))
    found = pmax_of_model(text).p_success_max
    assert found.value == pytest.approx(0.6782139, abs=1e-12)
    assert found.lower <= found.value <= found.upper
    assert found.upper - found.lower < 1e-10  # was [0.67821389999955, 1]
    stormpy = pytest.importorskip("stormpy")
    path = tmp_path / "model.prism"
    path.write_text(text)
    program = stormpy.parse_prism_program(str(path))
    prop = stormpy.parse_properties('Pmax=? [ F "success" ]', program)
    model = stormpy.build_model(program, prop)
    storm = float(stormpy.model_checking(model, prop[0]).get_value(model.initial_states[0]))
    assert found.lower - 1e-9 <= storm <= found.upper + 1e-9  # Storm's 1e-6 stopping rule
