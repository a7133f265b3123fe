"""Synthesis mode's text: ``strategy.mode``, the MDP template beside BS1's (whose output
must not change by a byte), its questions, and the commands that emit or refuse it.
Storm's reading of the MDP is in test_synthesis_model.py."""

from __future__ import annotations

import hashlib
import re
from collections import Counter
from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.cli import cli
from veribattery.config import config_to_yaml, load_config
from veribattery.errors import ConfigError
from veribattery.mission import EMITTED_FILES, check_mission, mission_dtmc, mission_files
from veribattery.render import (
    render_model,
    render_synthesis_model,
    render_synthesis_properties,
    synthesis_questions,
)

REPO = Path(__file__).resolve().parents[2]
SYNTHESIZE = "strategy.mode=synthesize"

#: sha256 over the four files ``emit`` wrote for each config before synthesis mode
#: existed (main at 47821a0): adding the mode must not change BS1's output by a byte.
BS1_EMITTED = {
    "example": "3b85af2bd4d1707bdc1c4874627fadd93d7abbbf113660a387f166edd6ebac59",
    "case1": "3b85af2bd4d1707bdc1c4874627fadd93d7abbbf113660a387f166edd6ebac59",
    "case2": "2d4bb3ac1e726111ee4a29b34ce115628cf9ceb7f11edbf198594d516a39855a",
    "case3": "7e1aeb62d8c57a04625671602ca5a2fa4cb5e0f2b5e948819709cc8edd9b1605",
    "case4": "0654aa3c975eea935f06f158b1370e92993d25c231416a3f2eed4ff730e42ff9",
    "basic_high": "c59fce67c5094ccc57adc96d169eb4ba0cb06e26d74acd880c377a44bc941e9d",
    "basic_medium": "ed3b406fb69d982f53edf362f9d997a126ef3231c6a725706d3108f1d4f5ea98",
    "basic_low": "22fede8ce161b8679e57d8c06dbef80712d54a8d2d6c4d16cf26ea26624a5d49",
}


def _config_path(name: str) -> Path:
    return REPO / "configs" / ("example.yaml" if name == "example" else f"paper/{name}.yaml")


def _code(text: str) -> str:
    """*text* without its comments."""
    return "\n".join(line.split("//")[0].rstrip() for line in text.splitlines())


@pytest.mark.parametrize("name", list(BS1_EMITTED))
def test_bs1_output_is_unchanged(name: str) -> None:
    digest = hashlib.sha256()
    for file, text in mission_files(load_config(_config_path(name))).as_mapping().items():
        digest.update(file.encode() + b"\0" + text.encode() + b"\0")
    assert digest.hexdigest() == BS1_EMITTED[name]


def test_mode_defaults_to_bs1_and_is_left_out_of_the_resolved_config() -> None:
    cfg = load_config("")
    assert cfg.strategy.mode == "bs1"
    assert "mode:" not in config_to_yaml(cfg)
    assert load_config("", ["strategy.mode=bs1"]) == cfg
    synth = load_config("", [SYNTHESIZE])
    assert "strategy:\n  safe_t: 0.3\n  mode: synthesize\n" in config_to_yaml(synth)
    assert load_config(config_to_yaml(synth)) == synth
    with pytest.raises(ConfigError, match=r"strategy\.mode: must be one of 'bs1' or "
                                          r"'synthesize', got 'optimal'"):
        load_config("strategy: {mode: optimal}")


def test_the_mdp_is_the_dtmc_with_its_decisions_left_open() -> None:
    cfg = load_config(_config_path("case1"), [SYNTHESIZE])
    mdp, dtmc = render_synthesis_model(cfg), render_model(cfg)
    # Up to the decisions, the DTMC's text but for a two-line synopsis and the type.
    synopsis = "\n".join(mdp.splitlines()[1:3]) + "\n"
    assert synopsis.startswith("// Synthesis mode: an MDP.")
    head = mdp.split("// The drone's choices")[0].replace(synopsis, "")
    assert head.replace("\nmdp\n", "\ndtmc\n") == dtmc.split("// Safety strategy BS1")[0]
    # From the Grid module on (Environment, Battery, rewards, labels): abort instead of
    # infeasible, line for line.
    wind = " true -> P_WSP_C:(wsp'=1-wsp) + (1-P_WSP_C):(wsp'=wsp);"
    ours = Counter(mdp.split("module Grid")[1].splitlines())
    theirs = Counter(dtmc.split("module Grid")[1].splitlines())
    assert ours - theirs == Counter(["  [abort]     " + wind,
                                     "  [abort]    true       -> (b'=0);"])
    assert theirs - ours == Counter(["  [infeasible]" + wind])
    code = _code(mdp)
    assert "infeasible" not in code and "ok_" not in code and "safe" not in code


def test_every_drone_action_moves_the_wind_and_nothing_else_does() -> None:
    mdp = render_synthesis_model(load_config("", [SYNTHESIZE]))
    drone = mdp.split("module Drone")[1].split("endmodule")[0]
    env = mdp.split("module Environment")[1].split("endmodule")[0]
    actions = re.findall(r"^\s*\[(\w+)\]", drone, flags=re.MULTILINE)
    assert actions == ["wait", "takeoff", "fly", "land", "inspect", "back", "next",
                       "backnext", "finish", "recharge", "oob", "abort"]
    assert re.findall(r"\[(\w+)\]", env) == actions
    assert "  [abort]    may_abort                      -> (s'=6);" in drone
    assert "formula may_abort = (s=0 & wsp=0) | (s>=1 & s<=4);" in mdp


def test_the_mdp_does_not_depend_on_safe_t() -> None:
    """Table 3's cases 1 and 2 differ only in safe_t: their MDPs only in the header."""
    one, two = (render_synthesis_model(load_config(_config_path(c))) for c in ("case1", "case2"))
    differ = [(a, b) for a, b in zip(one.splitlines(), two.splitlines(), strict=True) if a != b]
    assert differ == [("//     safe_t: 0.3", "//     safe_t: 0.25")]


def test_questions_from_requirements() -> None:
    cfg = load_config(
        "properties: {p_success: 'P=? [ F \"success\" ]', best: ' Pmax=?[F \"success\"] ',"
        " p_fail: 'P=? [ F \"failure\" ]', exp_mission_time: 'R{\"mt\"}=? [ F \"done\" ]'}\n"
        "requirements: ['p_success >= 0.99', 'best > 1/3', 'p_success <= 0.5',"
        " 'p_fail < 0.01', 'exp_mission_time < 5000']")
    fastest, skipped = synthesis_questions(cfg)
    assert [(q.name, q.op, str(q.bound)) for q in fastest] == [
        ("fastest_1", ">=", "99/100"), ("fastest_2", ">", "1/3")]
    assert [q.reason for q in skipped] == [
        "an upper bound on P(success): aborting at once meets it",
        "p_fail is P=? [ F \"failure\" ], not P=? [ F \"success\" ]",
        "exp_mission_time is R{\"mt\"}=? [ F \"done\" ], not P=? [ F \"success\" ]"]
    props = render_synthesis_properties(cfg)
    assert '"p_success_max": Pmax=? [ F "success" ];' in props
    assert '"fastest_1": multi(R{"mt"}min=? [ C ], P>=0.99 [ F "success" ]);' in props
    assert '"fastest_2": multi(R{"mt"}min=? [ C ], P>(1/3) [ F "success" ]);' in props
    assert "//   p_success <= 0.5: an upper bound on P(success)" in props
    assert len(re.findall(r'^"\w+":', props, flags=re.MULTILINE)) == 5
    # A bound no probability meets is bad input when the config is read, not a question.
    with pytest.raises(ConfigError, match=r"the bound must be in \[0, 1\], got 1.5"):
        load_config("requirements: ['p_success >= 1.5']")


def test_check_refuses_synthesis_mode_in_one_line(tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["check", str(_config_path("case1")), "--set", SYNTHESIZE])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.output
    assert lines[0].startswith("error: strategy.mode: synthesize makes the mission an MDP, "
                               "and this command verifies BS1's DTMC: use `veribattery "
                               "synthesize CONFIG`")
    cfg = load_config(_config_path("case1"), [SYNTHESIZE])
    for refused in (check_mission, mission_dtmc, mission_files):
        with pytest.raises(ConfigError, match=r"^strategy\.mode: synthesize makes"):
            refused(cfg)


def test_emit_writes_the_mdp_and_its_questions(tmp_path: Path) -> None:
    out = tmp_path / "out"
    args = ["emit", str(_config_path("case1")), "-o", str(out), "--set", SYNTHESIZE,
            "--set", 'requirements=["p_success >= 0.99", "exp_mission_time < 5000"]']
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines() == [str(out / name) for name in EMITTED_FILES]
    assert result.stderr.strip() == (
        "warning: requirement 'exp_mission_time < 5000' asks the MDP nothing: "
        "exp_mission_time is R{\"mt\"}=? [ F \"done\" ], not P=? [ F \"success\" ]")
    cfg = load_config(out / "config.resolved.yaml")
    assert cfg.strategy.mode == "synthesize"
    assert (out / "model.prism").read_text() == render_synthesis_model(cfg)
    props = (out / "properties.props").read_text()
    assert props.startswith("// PRISM and Storm both read this file (the model is an MDP)")
    assert props.endswith(render_synthesis_properties(cfg))
    assert "none is in Storm's own syntax" in (out / "storm-only.props").read_text()
