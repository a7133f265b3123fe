"""The emitted PRISM text: the spec's modules, variables, labels and integer-exact guards."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import veribattery.render.render as render_module
from veribattery.config import load_config
from veribattery.errors import ConfigError, RenderError
from veribattery.render import render_model, render_properties, template_dir

ACTIONS = (
    "wait",
    "takeoff",
    "infeasible",
    "fly",
    "land",
    "inspect",
    "back",
    "next",
    "backnext",
    "finish",
    "recharge",
    "oob",
)


def _model(*overrides: str) -> str:
    return render_model(load_config("", overrides))


def test_exactly_the_specs_variables_and_modules() -> None:
    text = _model()
    variables = re.findall(r"^\s*(\w+)\s*:\s*\[", text, flags=re.MULTILINE)
    assert sorted(variables) == ["b", "j", "k", "rc", "s", "wsp"]
    modules = re.findall(r"^module (\w+)", text, flags=re.MULTILINE)
    assert modules == ["Drone", "Grid", "Environment", "Battery"]
    assert text.count("endmodule") == 4
    assert "\ndtmc\n" in text


def test_environment_synchronises_on_every_action() -> None:
    env = _model().split("module Environment")[1].split("endmodule")[0]
    assert re.findall(r"\[(\w+)\]", env) == list(ACTIONS)


def test_labels_and_rewards() -> None:
    text = _model()
    assert 'label "success" = s=7;' in text
    assert 'label "failure" = s=6;' in text
    assert 'label "done" = s=6 | s=7;' in text
    assert 'rewards "mt"' in text and 'rewards "rc"' in text
    assert "[recharge] true : 1;" in text


def test_guards_are_integer_comparisons() -> None:
    text = _model()
    assert "formula volt = 4*b > 3*cap ? 2 : (4*b < cap ? 0 : 1);" in text
    assert "formula ok_fly = 10*(b - (c_fly + c_ins)) >= 3*cap;" in text
    assert "formula cap = floor(C_NEW*(500 - rc)/500);" in text
    code = "\n".join(line.split("//")[0] for line in text.splitlines())
    assert not re.search(r"b\s*/\s*cap", code)
    floats = set(re.findall(r"\d+\.\d+", code))
    assert floats == {"0.1"}  # only P_WSP_C, a probability


def test_risky_strategy_uses_its_own_ratio() -> None:
    assert "formula ok_ins = 4*(b - c_ins) >= cap;" in _model("strategy.safe_t=0.25")


def test_domain_guards_keep_updates_in_range() -> None:
    text = _model()
    assert "[inspect]  j<J_MAX -> (j'=j+1);" in text
    assert "[fly]      b>=c_fly   -> (b'=b-c_fly);" in text
    assert "[recharge] rc<RC_MAX  -> (rc'=rc+1) & (b'=cap_next);" in text


def test_header_records_the_resolved_config() -> None:
    text = render_model(load_config("strategy: {safe_t: 0.25}"))
    assert "//     safe_t: 0.25\n" in text
    assert "//     capacity_ah: 11\n" in text


def test_basic_model_fixes_level_and_capacity() -> None:
    text = _model("battery.model=basic_medium")
    assert "formula volt = 1;" in text
    assert "formula cap = C_NEW;" in text


def test_per_cell_values_follow_the_route() -> None:
    text = _model()
    assert "    k=0 ? 4 : k=1 ? 3 : k=2 ? 2 : k=3 ? 3 : k=4 ? 4 :\n" in text
    assert "formula step = 1;" in text
    assert "const int K = 25;" in text
    text = _model(
        "farm.cols=3", "farm.rows=3", "farm.base=[0,0]", "farm.route=[[0,0],[1,1],[1,0],[0,1]]"
    )
    assert "formula step =\n    k=0 ? 2 : k=1 ? 1 :\n    2;" in text


def test_degenerate_wind_probabilities() -> None:
    assert "[wait]       true -> true;" in _model("environment.p_wsp_c=0")
    assert "[wait]       true -> (wsp'=1-wsp);" in _model("environment.p_wsp_c=1")


def test_decimal_times_become_doubles() -> None:
    assert "const double T_WAIT = 0.5;" in _model("times_min.wait=0.5")


def test_prism_integer_overflow_is_refused() -> None:
    with pytest.raises(ConfigError, match="32-bit"):
        _model("battery.fade_per_recharge=0.0000001", "battery.capacity_ah=1000")


def test_properties_file() -> None:
    text = render_properties(load_config("requirements: ['p_success >= 0.99']"))
    assert '"p_success": P=? [ F "success" ];' in text
    assert '"exp_recharges": R{"rc"}=? [ F "done" ];' in text
    assert "// Requirements: p_success >= 0.99" in text


def test_templates_come_from_the_source_tree() -> None:
    assert (template_dir() / "model.prism.j2").is_file()


def test_template_errors_become_render_errors(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "model.prism.j2").write_text("{{ p.no_such_field }}")
    (tmp_path / "properties.props.j2").write_text("{% for %}")
    monkeypatch.setattr(render_module, "template_dir", lambda: tmp_path)
    cfg = load_config("")
    with pytest.raises(RenderError, match="no_such_field"):
        render_model(cfg)
    with pytest.raises(RenderError, match=r"properties\.props\.j2:1"):
        render_properties(cfg)
