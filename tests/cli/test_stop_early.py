"""Exploration stops where every property is decided (Storm's terminal states).

The model below has six reachable states; ``s=1`` is the target of the properties, and
``s=4`` and ``s=5`` are reached only through it. Its values are solved by hand: with
``a`` from ``s=0``, ``V0 = 1/2 + 1/2 V2`` and ``V2 = 1/2 V0 + 1/2`` for ``F s=1``
(``V0 = 1``), and for the expected steps ``R0 = 1 + 1/2 R2``, ``R2 = 1 + 1/2 R0``
(``R0 = 2``); ``b`` goes to the sink ``s=3`` (``Pmin = 0``). Its DTMC twin goes from
``s=0`` to ``s=1``, ``s=2``, ``s=3`` with 1/2, 1/4, 1/4: ``V0 = 1/2 + 1/4 V2``, ``V2 =
1/2 V0 + 1/2``, so ``V0 = 5/7``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.cli.terminal import run_in_terminal
from veribattery.cli import cli
from veribattery.lang import parse_properties
from veribattery.pipeline import check_prism_file

MODEL = """mdp
module m
  s : [0..5] init 0;
  [a] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);
  [b] s=0 -> (s'=3);
  [] s=1 -> (s'=4);
  [] s=4 -> (s'=5);
  [] s=5 -> true;
  [] s=2 -> 0.5:(s'=0) + 0.5:(s'=1);
  [] s=3 -> true;
endmodule
label "goal" = s=1;
rewards "steps" true : 1; endrewards
"""

DTMC = """dtmc
module m
  s : [0..5] init 0;
  [] s=0 -> 0.5:(s'=1) + 0.25:(s'=2) + 0.25:(s'=3);
  [] s=1 -> (s'=4);
  [] s=4 -> (s'=5);
  [] s=5 -> true;
  [] s=2 -> 0.5:(s'=0) + 0.5:(s'=1);
  [] s=3 -> true;
endmodule
"""

#: (property, value, states built, states left unexpanded).
STOPPING = [
    ('Pmax=? [ F "goal" ]', 1.0, 4, 1),
    ("Pmin=? [ F s=1 ]", 0.0, 4, 1),
    ("Pmax=? [ F<=3 s=1 ]", 0.875, 4, 1),
    ("Pmax=? [ s!=3 U s=1 ]", 1.0, 4, 2),
    ("Pmin=? [ G s!=1 ]", 0.0, 4, 1),
    ('R{"steps"}min=? [ F s=1 ]', 2.0, 4, 1),
    ('1 - Pmax=? [ F s=1 ]', 0.0, 4, 1),
    # the initial state decided: a chunk of the search with nothing to expand
    ("Pmax=? [ F s=0 ]", 1.0, 1, 1),
]
#: Properties that read past the target: every state is built.
READING_ON = [
    ("Pmax=? [ F>=2 s=4 ]", 1.0),
    ("Pmax=? [ X s=1 ]", 0.5),
    ('R{"steps"}max=? [ C<=3 ]', 3.0),
    ('filter(forall, Pmax>=1 [ F s=5 ], s=1)', True),
    ("Pmax=? [ F s=1 & Pmax>0.5 [ X s=4 ] ]", 1.0),
    ('Pmax=? [ F "deadlock" ]', 0.0),
]


def _run(tmp_path: Path, prop: str, stop_early: bool):  # type: ignore[no-untyped-def]
    model = tmp_path / "m.nm"
    model.write_text(MODEL)
    return check_prism_file(model, props_source=prop, stop_early=stop_early)


@pytest.mark.parametrize(("prop", "value", "states", "stopped"), STOPPING)
def test_exploration_stops_where_the_property_is_decided(
        tmp_path: Path, prop: str, value: float, states: int, stopped: int) -> None:
    early = _run(tmp_path, prop, True)
    full = _run(tmp_path, prop, False)
    assert early.model_summary["states"] == states
    assert early.model_summary["stopped_states"] == stopped
    assert full.model_summary["states"] == 6
    assert "stopped_states" not in full.model_summary
    assert early.results[0].value == pytest.approx(value, abs=1e-12)
    assert full.results[0].value == pytest.approx(value, abs=1e-12)


@pytest.mark.parametrize(("prop", "value"), READING_ON)
def test_a_property_that_reads_past_the_target_builds_every_state(
        tmp_path: Path, prop: str, value: float | bool) -> None:
    run = _run(tmp_path, prop, True)
    assert run.model_summary["states"] == 6
    assert "stopped_states" not in run.model_summary
    assert run.results[0].value == pytest.approx(value, abs=1e-12)


@pytest.mark.parametrize(("prop", "value", "states", "stopped"), [
    ("P=? [ F s=1 ]", 5 / 7, 4, 1),
    ("P=? [ s!=3 U s=1 ]", 5 / 7, 4, 2),
    ("P>0.7 [ F<=40 s=1 ]", True, 4, 1),
    ("P=? [ X s=1 ]", 0.5, 6, 0),
    ("P=? [ F s=0 ]", 1.0, 1, 1),
])
def test_a_dtmc_stops_alike(tmp_path: Path, prop: str, value: float | bool, states: int,
                            stopped: int) -> None:
    model = tmp_path / "m.pm"
    model.write_text(DTMC)
    early = check_prism_file(model, props_source=prop, stop_early=True, keep="answers")
    full = check_prism_file(model, props_source=prop, stop_early=False, keep="answers")
    assert early.model_summary["states"] == states
    assert early.model_summary.get("stopped_states", 0) == stopped
    assert full.model_summary["states"] == 6
    assert early.results[0].value == pytest.approx(value, abs=1e-12)
    assert full.results[0].value == pytest.approx(value, abs=1e-12)
    # keeping every state's value, the whole chain is built
    kept = check_prism_file(model, props_source=prop, stop_early=True, keep="states")
    assert kept.model_summary["states"] == 6


def test_several_properties_stop_only_where_all_are_decided(tmp_path: Path) -> None:
    model = tmp_path / "m.nm"
    model.write_text(MODEL)
    # F s=1 is decided at s=1, F s=4 at s=4: no state decides both, and s=5 is reached
    both = check_prism_file(model, props_source="Pmax=? [ F s=1 ]\nPmax=? [ F s=4 ]\n",
                            stop_early=True)
    assert both.model_summary["states"] == 6
    assert [r.value for r in both.results] == pytest.approx([1.0, 1.0])
    # ... but s=1 | s=3 (U's) and s=1 (F's) together: s=1
    joint = check_prism_file(model, props_source="Pmax=? [ F s=1 ]\nPmin=? [ s!=3 U s=1 ]\n",
                             stop_early=True)
    assert joint.model_summary["states"] == 4
    assert joint.model_summary["stopped_states"] == 1


def test_the_cli_stops_by_default_and_all_states_builds_them(tmp_path: Path) -> None:
    (tmp_path / "m.nm").write_text(MODEL)
    runner = CliRunner()
    args = ["prism", str(tmp_path / "m.nm"), "--property", "Pmax=? [ F s=1 ]", "--json"]
    early = json.loads(runner.invoke(cli, args).output)
    full = json.loads(runner.invoke(cli, [*args, "--all-states"]).output)
    exported = runner.invoke(cli, [*args, "--export-strategy", str(tmp_path / "s.txt")])
    assert early["model"]["states"] == 4
    assert early["model"]["stopped_states"] == 1
    assert full["model"]["states"] == 6
    assert "stopped_states" not in full["model"]
    assert early["results"][0]["value"] == full["results"][0]["value"] == 1.0
    assert exported.exit_code == 0
    assert '"states": 6,' in exported.output  # a strategy covers every state


def test_the_terminal_says_how_many_states_were_left_unexpanded(tmp_path: Path) -> None:
    (tmp_path / "m.nm").write_text(MODEL)
    screen = run_in_terminal(["prism", "m.nm", "--property", "Pmax=? [ s!=3 U s=1 ]"], 80,
                             tmp_path)
    assert screen.status == 0
    assert "Model: 4 states, 5 choices, 7 transitions, 1 initial, 0 deadlocks" in screen.text
    assert ("2 states left unexpanded: every property is decided there (--all-states)"
            in screen.text)
    assert screen.widest <= 80


def test_properties_parse_as_the_cli_reads_them() -> None:
    """The table's formulas are all properties the parser takes (no typo hides a case)."""
    texts = [p for p, *_ in STOPPING] + [p for p, _ in READING_ON]
    parsed = parse_properties("\n".join(texts) + "\n")
    assert len(parsed.properties) == len(texts)


def test_an_error_past_the_decided_states_is_found_with_all_states(tmp_path: Path) -> None:
    """The build stops at ``x=1``, where ``F x=1`` is decided, before the update that
    leaves ``x``'s range: as Storm, it answers; ``--all-states`` builds on, as PRISM,
    and reports the error."""
    model = tmp_path / "m.pm"
    model.write_text("dtmc\nmodule m\n  x : [0..1] init 0;\n  [] true -> (x'=x+1);\nendmodule\n")
    args = ["prism", str(model), "--property", "P=? [ F x=1 ]", "--json"]
    early = CliRunner().invoke(cli, args)
    assert early.exit_code == 0
    assert json.loads(early.stdout)["results"][0]["value"] == 1.0
    whole = CliRunner().invoke(cli, [*args, "--all-states"])
    assert whole.exit_code == 2
    assert whole.stderr.startswith("error:") and "x" in whole.stderr
