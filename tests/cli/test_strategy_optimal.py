"""``explain``, ``simulate`` and ``distribution --strategy optimal``: the mission under
synthesize's strategy (safest, then fastest), whose values synthesize reports."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner, Result

from tests.cli.inputs import CASE1, SYNTHESIS
from veribattery.cli import cli
from veribattery.cli.explain import failure_notes


def _run(command: str, *args: str) -> Result:
    return CliRunner().invoke(cli, [command, CASE1, *SYNTHESIS, *args])


def _json(command: str, *args: str) -> Any:
    result = _run(command, *args, "--format", "json")
    assert result.exit_code == 0, result.stderr
    return json.loads(result.stdout)


@pytest.fixture(scope="module")
def strategy() -> dict[str, Any]:
    """synthesize's own values of its strategy (the 3x2 farm at 6 Ah)."""
    document = _json("synthesize")
    own = dict(document["strategy"])
    # The strategy is the safest: it attains Pmax, above BS1's P(success) on this farm.
    assert own["p_success"] == pytest.approx(document["results"]["p_success_max"], rel=1e-12)
    assert own["p_success"] > document["bs1"]["p_success"] + 0.01
    return own


def test_distribution_gives_the_strategys_p_success(strategy: dict[str, Any]) -> None:
    found = _json("distribution", "--strategy", "optimal")
    assert found["p_success"] == pytest.approx(strategy["p_success"], rel=1e-9, abs=1e-12)
    assert found["p_success"] + found["p_failure"] == pytest.approx(1.0, abs=1e-12)
    assert found["pending"] == 0.0
    # BS1's mission is another chain: its P(success) is synthesize's BS1 value, lower.
    bs1 = _json("distribution")
    assert bs1["p_success"] < found["p_success"] - 0.01


def test_explain_breaks_down_the_strategys_failures(strategy: dict[str, Any]) -> None:
    found = _json("explain", "--strategy", "optimal", "--top", "2")
    p_failure = 1.0 - strategy["p_success"]
    assert found["p_failure"] == pytest.approx(p_failure, rel=1e-9, abs=1e-12)
    for grouping, records in found["breakdown"].items():
        total = sum(r["probability"] for r in records)
        assert total == pytest.approx(p_failure, rel=1e-9), grouping
    # Each state shows the one action the strategy takes, not the MDP's enabled ones.
    actions = {r["action"] for r in found["breakdown"]["state+action"]}
    assert actions and not any("|" in a for a in actions)
    steps = [s["action"] for p in found["paths"] for s in p["states"]]
    assert "takeoff" in steps and not any("|" in a for a in steps)


def test_explain_notes_only_the_failures_it_shows() -> None:
    """The strategy fails by giving up only: the note on oob (out of battery) was printed
    under every table all the same."""
    result = _run("explain", "--strategy", "optimal", "--top", "1", "--by", "action")
    assert result.exit_code == 0, result.stderr
    lines = result.stdout.splitlines()
    assert any(line.split()[:1] == ["abort"] for line in lines)  # the by-action table
    assert "oob" not in result.stdout
    assert lines[-1] == "abort: the strategy gives the mission up there, and it fails."


@pytest.mark.parametrize(("actions", "notes"), [
    (["takeoff", "abort", ""], ["abort"]),
    (["oob (land)", "fly"], ["oob (X)"]),
    (["oob (recharge cap)"], ["oob (recharge cap)"]),
    (["abort", "oob (recharge cap)", "oob (land)"], ["oob (X)", "oob (recharge cap)", "abort"]),
    (["takeoff", "fly"], []),
])
def test_a_failure_note_is_given_for_an_action_shown(actions: list[str],
                                                     notes: list[str]) -> None:
    assert [note.partition(":")[0] for note in failure_notes(actions)] == notes


def test_simulate_estimates_the_strategys_values(strategy: dict[str, Any]) -> None:
    found = _json("simulate", "--strategy", "optimal", "--runs", "3000", "--seed", "1")
    results = found["results"]
    assert set(results) == {"p_success", "exp_mission_time", "exp_recharges"}
    for name, estimate in results.items():
        assert estimate["value"] == strategy[name]
        assert estimate["runs"] == 3000 and estimate["undecided"] == 0
        low, high = estimate["ci95"]
        assert low <= strategy[name] <= high, name


def test_bs1_is_the_default_and_unchanged() -> None:
    default = _run("distribution", "--format", "json")
    named = _run("distribution", "--strategy", "bs1", "--format", "json")
    assert default.exit_code == named.exit_code == 0
    assert default.stdout == named.stdout


@pytest.mark.parametrize("command", ["explain", "simulate", "distribution"])
def test_an_unknown_strategy_is_one_line_exit_2(command: str) -> None:
    extra = ("--runs", "10") if command == "simulate" else ()
    result = _run(command, "--strategy", "best", *extra)
    assert result.exit_code == 2
    assert result.stderr.strip().splitlines() == [
        "error: --strategy must be bs1, optimal or a strategy file; no file 'best'"]


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """synthesize's strategy in both formats (strategy.json, strategy.txt)."""
    folder = tmp_path_factory.mktemp("strategy")
    for name in ("strategy.json", "strategy.txt"):
        result = _run("synthesize", "--export-strategy", str(folder / name))
        assert result.exit_code == 0, result.stderr
    return folder


@pytest.mark.parametrize("name", ["strategy.json", "strategy.txt"])
def test_an_exported_strategy_file_is_the_strategy(exported: Path, name: str,
                                                   strategy: dict[str, Any]) -> None:
    path = str(exported / name)
    found = _json("distribution", "--strategy", path)
    assert found == _json("distribution", "--strategy", "optimal")
    estimates = _json("simulate", "--strategy", path, "--runs", "500")["results"]
    for key, estimate in estimates.items():
        # Checked on the induced DTMC here, certified on the MDP by synthesize.
        assert estimate["value"] == pytest.approx(strategy[key], rel=1e-9)
    explained = _json("explain", "--strategy", path, "--top", "1")
    assert explained == _json("explain", "--strategy", "optimal", "--top", "1")


def test_a_strategy_file_of_another_model_is_refused(exported: Path, tmp_path: Path) -> None:
    # At 5 Ah the charge levels differ: the file names states the MDP does not have.
    result = _run("distribution", "--strategy", str(exported / "strategy.txt"),
                  "--set", "battery.capacity_ah=5")
    assert result.exit_code == 2
    assert len(result.stderr.strip().splitlines()) == 1
    assert re.search(r"strategy\.txt:\d+: \([\d,]+\) is no state of the mission MDP \(a "
                     r"strategy exported for another config\?\)", result.stderr), result.stderr
    lines = (exported / "strategy.txt").read_text(encoding="utf-8").splitlines()
    cut = tmp_path / "cut.txt"
    cut.write_text("\n".join(lines[:-40]) + "\n", encoding="utf-8")
    result = _run("explain", "--strategy", str(cut))
    assert result.exit_code == 2
    named = re.search(r"cut\.txt:(\d+): its action leads to (\([\d,]+\)), which the file "
                      "does not name", result.stderr)
    assert named is not None, result.stderr
    # (the state it names is one of those cut, and the line is one of those kept)
    assert any(line.startswith(named[2] + "=") for line in lines[-40:])
    assert 1 <= int(named[1]) <= len(lines) - 40
    wrong = tmp_path / "wrong.txt"
    wrong.write_text(lines[0].rpartition("=")[0] + "=fly\n", encoding="utf-8")
    result = _run("explain", "--strategy", str(wrong))
    assert result.exit_code == 2
    assert "wrong.txt:1: 'fly' is not exactly one choice of that state" in result.stderr


@pytest.mark.parametrize(("edit", "expected"), [
    (lambda lines: [*lines, lines[0]], ":{last}: names the state of line 1 again; give each "
                                       "state one action"),
    (lambda lines: [lines[0].replace("(", "(0,", 1), *lines[1:]],
     ":1: a state of 7 values, but the model has 6 variables (a strategy for another model?)"),
    (lambda lines: [*lines[:2], lines[2].rpartition("=")[0] + "=fly_to_mars", *lines[3:]],
     ":3: action 'fly_to_mars' is no action of the mission MDP (its actions: abort, "),
], ids=["twice", "arity", "unknown-action"])
def test_a_strategy_file_error_names_its_line(exported: Path, tmp_path: Path, edit: Any,
                                              expected: str) -> None:
    lines = (exported / "strategy.txt").read_text(encoding="utf-8").splitlines()
    edited = edit(lines)
    path = tmp_path / "edited.txt"
    path.write_text("\n".join(edited) + "\n", encoding="utf-8")
    result = _run("explain", "--strategy", str(path))
    assert result.exit_code == 2
    assert f"edited.txt{expected.replace('{last}', str(len(edited)))}" in result.stderr, \
        result.stderr


@pytest.mark.parametrize("command", ["explain", "simulate", "distribution"])
@pytest.mark.parametrize(("name", "edit", "expected"), [
    ("strategy.txt", lambda data: data.replace(b"(0,", b"(99999999999999999999,", 1),
     ":1: '99999999999999999999' is not a variable's value"),
    ("strategy.json", lambda data: data.replace(b'"b": 60', b'"b": 99999999999999999999', 1),
     ":1: 99999999999999999999 is not a variable's value"),
    # the line after the file's last: its count of newlines + 1
    ("strategy.txt", lambda data: data + b"(\xff)=x\n", ":{end}:2: not UTF-8 text (byte 0xff)"),
], ids=["beyond-int64", "json-beyond-int64", "not-utf8"])
def test_a_damaged_strategy_file_is_one_line_exit_2(exported: Path, tmp_path: Path,
                                                    command: str, name: str, edit: Any,
                                                    expected: str) -> None:
    """A value beyond numpy's int64 raised OverflowError, a byte that is not UTF-8 a
    UnicodeDecodeError: tracebacks, exit 1."""
    damaged = tmp_path / name
    damaged.write_bytes(edit((exported / name).read_bytes()))
    expected = expected.replace("{end}", str((exported / name).read_bytes().count(b"\n") + 1))
    extra = ("--runs", "5") if command == "simulate" else ()
    result = _run(command, "--strategy", str(damaged), *extra)
    assert result.exit_code == 2, result.output
    assert result.stderr.strip().splitlines() == [result.stderr.strip()]
    assert result.stderr.startswith(f"error: {damaged}{expected}"), result.stderr


def test_the_strategy_view_names_the_action_taken() -> None:
    """Unit check of the view: the strategy's action, the model's name where unlabelled."""
    from veribattery.analyses.mission_view import MissionModel
    from veribattery.analyses.strategy_view import StrategyView
    from veribattery.config import load_config
    from veribattery.synthesis.induced_dtmc import optimal_mission

    cfg = load_config(CASE1, [SYNTHESIS[i] for i in range(1, len(SYNTHESIS), 2)])
    induced = optimal_mission(cfg)
    view = StrategyView(MissionModel(cfg, induced.flat, induced.dtmc), induced.actions)
    states = np.arange(induced.dtmc.num_states)
    shown = view.columns(states)["action"]
    labelled = induced.actions != ""
    assert (shown[labelled] == induced.actions[labelled]).all()
    assert set(shown[~labelled].tolist()) == {"Drone"}
    with pytest.raises(ValueError, match="3 actions for 707 states"):
        StrategyView(MissionModel(cfg, induced.flat, induced.dtmc), induced.actions[:3])


@pytest.mark.parametrize(("text", "expected"), [
    ('{"x": 1}', "not a Storm scheduler: expected a list of entries"),
    ('[{"s": {"x": 0}}]', 'entry 1\'s "s" has no value of s, k, j, wsp, b, rc'),
    ('[{"c": []}]', 'entry 1 has no "s"'),
    ("[{", "not JSON (Expecting"),
])
def test_a_broken_storm_scheduler_is_named_in_its_terms(tmp_path: Path, text: str,
                                                        expected: str) -> None:
    """Not Python's KeyError('s') or TypeError: what the file lacks, and where."""
    broken = tmp_path / "broken.json"
    broken.write_text(text, encoding="utf-8")
    result = _run("explain", "--strategy", str(broken))
    assert result.exit_code == 2
    assert expected in result.stderr, result.stderr
    assert "Error(" not in result.stderr
