"""Progress on stderr -- plain lines when it is not a terminal, a spinner when it is --
and ``--max-states``."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from tests.cli.inputs import CASE1, SMALL, SYNTHESIS
from tests.cli.terminal import run_in_terminal
from veribattery.cli import cli, progress
from veribattery.errors import OptionError

NAND = Path(__file__).resolve().parents[2] / "bench" / "qcomp" / "nand"
#: nand N=5 K=1: 930 states, found over dozens of BFS layers.
ARGS = ["prism", str(NAND / "nand.prism"), "--props", str(NAND / "nand.props"),
        "--property", "reliable", "--const", "N=5", "--const", "K=1", "--json"]


class _Clock:
    """A clock that moves only when told to."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_plain_lines_start_after_the_first_interval_then_come_every_interval() -> None:
    lines: list[str] = []
    clock = _Clock()
    watch = progress.PlainProgress(lines.append, clock, first=5.0, every=10.0)
    for t, states in ((1.0, 10), (4.9, 20), (5.0, 500), (14.0, 600), (15.0, 1000), (20.0, 1200)):
        clock.now = 100.0 + t
        watch(states, 7)
    assert lines == ["exploring states: 500 found, frontier 7, 100 states/s, 5 s",
                     "exploring states: 1,000 found, frontier 7, 67 states/s, 15 s"]


def _run(*extra: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, [*ARGS, *extra])
    return result.exit_code, result.stdout, result.stderr


def test_a_slow_build_prints_lines_on_stderr_and_leaves_stdout_alone(
        monkeypatch: pytest.MonkeyPatch) -> None:
    code, quiet_out, quiet_err = _run()
    assert code == 0 and "exploring states" not in quiet_err
    # Every layer "slow": a line per layer, from the first.
    monkeypatch.setattr(progress, "FIRST_LINE_S", 0.0)
    monkeypatch.setattr(progress, "LINE_EVERY_S", 0.0)
    code, out, err = _run()
    assert code == 0
    lines = [line for line in err.splitlines() if line.startswith("exploring states: ")]
    assert len(lines) >= 2 and lines[-1].startswith("exploring states: 930 found, ")
    assert all("states/s" in line for line in lines)
    document, quiet = json.loads(out), json.loads(quiet_out)
    assert document["results"] == quiet["results"]
    assert document["model"] == quiet["model"] and document["model"]["states"] == 930


def test_max_states_stops_the_build_with_one_line_exit_2() -> None:
    code, out, err = _run("--max-states", "500")
    assert code == 2 and out == ""
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1
    assert "--max-states 500" in lines[0] and "states" in lines[0]


def test_max_states_above_the_size_changes_nothing() -> None:
    code, out, _ = _run("--max-states", "930")
    assert code == 0
    assert json.loads(out)["results"] == json.loads(_run()[1])["results"]


def test_check_max_states_stops_a_mission_build() -> None:
    base = ["check", CASE1, *SMALL, "--format", "json"]
    states = json.loads(CliRunner().invoke(cli, base).stdout)["model"]["states"]
    stopped = CliRunner().invoke(cli, [*base, "--max-states", str(states // 2)])
    assert stopped.exit_code == 2 and stopped.stdout == ""
    assert f"--max-states {states // 2:,}" in stopped.stderr
    assert CliRunner().invoke(cli, [*base, "--max-states", str(states)]).exit_code == 0


def test_stages_wait_for_the_first_line_then_are_told_as_they_begin() -> None:
    lines: list[str] = []
    clock = _Clock()
    watch = progress.PlainProgress(lines.append, clock, first=5.0, every=10.0)
    watch.starting("building the state space")
    watch(100, 10)
    clock.now += 1.0
    watch.checking(1, 2, "P=? [ F a ]")
    clock.now += 1.0
    watch.solving(50, 400, "states")  # 2 s in: a short run says nothing
    assert lines == []
    clock.now += 3.5  # 5.5 s in: the first line, after the stage it belongs to
    watch.solving(300, 400, "states")
    clock.now += 1.0
    watch.solving(400, 400, "states")  # within the interval: nothing
    watch.checking(2, 2, 'R{"time"}=? [ F b ]')  # a long run: told at once
    clock.now += 10.0
    watch.solving(7, 20_000, "iterations")
    assert lines == ["checking property 1 of 2: P=? [ F a ]",
                     "solving P=? [ F a ]: 300 of 400 states, 4 s",
                     'checking property 2 of 2: R{"time"}=? [ F b ]',
                     'solving R{"time"}=? [ F b ]: 7 of 20,000 iterations, 10 s']


def test_steps_of_a_run_without_counts_are_told_once_it_is_long() -> None:
    """A forecast's ages report no state counts: its steps start the lines themselves."""
    lines: list[str] = []
    clock = _Clock()
    watch = progress.PlainProgress(lines.append, clock, first=5.0, every=10.0)
    for t, cycle in ((0.0, 30), (2.0, 40), (5.5, 50), (6.0, 60)):
        clock.now = 100.0 + t
        watch.step(f"checking cycle {cycle}")
    assert lines == ["checking cycle 50", "checking cycle 60"]


def test_a_stage_before_the_first_build_line_is_written_with_it() -> None:
    lines: list[str] = []
    clock = _Clock()
    watch = progress.PlainProgress(lines.append, clock, first=0.0, every=0.0)
    watch.starting("building the state space")
    watch(12, 3)
    assert lines == ["building the state space",
                     "exploring states: 12 found, frontier 3, … states/s, 0 s"]


def test_the_state_limit_passes_stages_and_solves_on() -> None:
    lines: list[str] = []
    watch = progress.PlainProgress(lines.append, _Clock(), first=0.0, every=0.0)
    limited = progress.limited(watch, 10)
    assert limited is not None
    limited.starting("building the state space")
    limited(10, 1)
    limited.checking(1, 1, "P=? [ F a ]")
    limited.solving(3, 9, "states")
    assert lines[0] == "building the state space" and lines[-1].startswith(
        "solving P=? [ F a ]: 3 of 9 states, ")
    with pytest.raises(Exception, match="--max-states 10"):
        limited(11, 1)


@pytest.mark.parametrize(("value", "expected"), [(None, (None, None)), ("0,0", (0.0, 0.0)),
                                                  ("0.5, 2", (0.5, 2.0))])
def test_the_intervals_come_from_the_environment(
        monkeypatch: pytest.MonkeyPatch, value: str | None,
        expected: tuple[float | None, float | None]) -> None:
    if value is None:
        monkeypatch.delenv(progress.INTERVALS_VARIABLE, raising=False)
    else:
        monkeypatch.setenv(progress.INTERVALS_VARIABLE, value)
    assert progress.intervals() == expected


@pytest.mark.parametrize("value", ["5", "a,b", "-1,2", "1,2,3"])
def test_bad_intervals_are_a_user_error(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    monkeypatch.setenv(progress.INTERVALS_VARIABLE, value)
    with pytest.raises(OptionError, match=progress.INTERVALS_VARIABLE):
        progress.intervals()


#: What a check says on stderr, a line per report with intervals of 0.
_SOLVING = re.compile(r"^solving P=\? \[ F s=4 & z/N<0\.1 \]: (\d+) of 668 states, \d+ s$")


def _piped(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    """``veribattery ARGS`` (or *args*) with stdout and stderr pipes (as in CI or
    ``2> log``)."""
    command = [sys.executable, "-c", "from veribattery.cli import main; main()",
               *(args or ARGS)]
    return subprocess.run(command, capture_output=True, text=True, check=True,
                          env={**os.environ, **env})


#: The environment that makes every report a line.
_EVERY = {progress.INTERVALS_VARIABLE: "0,0"}


def test_a_long_check_tells_its_stages_and_solves_on_a_pipe() -> None:
    quiet = _piped({})
    assert quiet.stderr == ""  # a short run prints nothing
    told = _piped(_EVERY)
    lines = told.stderr.splitlines()
    assert lines[0] == "building the state space"
    stages = [line for line in lines if not line.startswith(("exploring", "solving"))]
    assert stages == ["building the state space", "preparing the linear systems",
                      "checking property 1 of 1: P=? [ F s=4 & z/N<0.1 ]"]
    solved = [int(m.group(1)) for m in map(_SOLVING.match, lines) if m is not None]
    assert solved[:2] == [0, 668] and len(solved) == sum(1 for x in lines if "solving" in x)
    document = json.loads(told.stdout)
    assert document["results"] == json.loads(quiet.stdout)["results"]


def test_check_tells_the_same_lines_as_prism_and_keeps_its_json(
        monkeypatch: pytest.MonkeyPatch) -> None:
    quiet, told, lines = _quiet_then_told(monkeypatch, "check")
    assert any(line.startswith("exploring states: ") for line in lines)
    checking = [line for line in lines if line.startswith("checking property ")]
    count = len(json.loads(quiet.stdout)["results"])
    assert checking and all(f" of {count}: " in line for line in checking)
    assert any(line.startswith("solving ") and " states, " in line for line in lines)
    assert json.loads(told.stdout)["results"] == json.loads(quiet.stdout)["results"]


def test_the_spinner_shows_the_solve_and_leaves_a_clean_screen(tmp_path: Path) -> None:
    screen = run_in_terminal(ARGS[:-1], 80, tmp_path)
    assert screen.status == 0, screen.text
    # The spinner's last text (rich draws it once more as it stops), then erased.
    assert "solving P=? [ F s=4 & z/N<0.1 ]: " in screen.drawn, screen.drawn
    assert " of 668 states, " in screen.drawn
    assert "solving" not in screen.text and "0.587216625261" in screen.text


def test_bad_intervals_are_refused_on_a_terminal_too(tmp_path: Path) -> None:
    # the spinner does not use them, but a value the user set and mistyped is reported
    screen = run_in_terminal(ARGS[:-1], 80, tmp_path, env={progress.INTERVALS_VARIABLE: "oops"})
    assert screen.status == 2, screen.text
    assert screen.lines == (f"error: {progress.INTERVALS_VARIABLE}='oops': give FIRST,EVERY "
                            "seconds, e.g. 0,1",), screen.text


def test_a_long_formula_is_cut_on_the_spinner_not_wrapped(tmp_path: Path) -> None:
    """The formula is cut, not the count: how far the solve is stays in view."""
    formula = "P=? [ F s=4 & " + " & ".join(["z/N<0.1"] * 12) + " ]"
    args = [arg if arg != "reliable" else formula for arg in ARGS[:-1]]
    screen = run_in_terminal(args, 80, tmp_path)
    assert screen.status == 0, screen.text
    drawn = [part for part in re.split(r"[\r\n]", screen.drawn) if "solving" in part]
    assert drawn and all(len(part) <= 80 for part in drawn), drawn
    assert any(re.search(r"z/N…: \d+ of 668 states, \d+ s$", part) for part in drawn), drawn


def test_a_long_subject_keeps_the_count_in_the_room_given() -> None:
    subject = "Pmin=? [ F^{rew{\"time\"}<=deadline} ((s1=8) & (s2=7)) | ((s1=7) & (s2=8))]"
    line = progress.solve_text(subject, 113, 201, "reward layers", 4.2, room=78)
    assert line == ("solving Pmin=? [ F^{rew{\"time\"}<=deadline} ((s…: 113 of 201 reward "
                    "layers, 4 s")
    assert len(line) == 78
    assert progress.solve_text("P=? [ F a ]", 3, 9, "steps", 1.0, room=78) == (
        "solving P=? [ F a ]: 3 of 9 steps, 1 s")
    assert progress.solve_text(subject, 3, 9, "steps", 1.0, room=20) == "solving: 3 of 9 steps, 1 s"


def test_a_step_bounded_check_tells_its_steps_on_a_pipe(tmp_path: Path) -> None:
    model = tmp_path / "walk.pm"
    model.write_text("dtmc\nmodule w\n x : [0..50] init 0;\n"
                     " [] x<50 -> 0.5:(x'=x+1) + 0.5:(x'=x);\n [] x=50 -> true;\nendmodule\n")
    told = _piped(_EVERY, "prism", str(model), "--property", "P=? [ F<=60 x=50 ]", "--json")
    steps = re.findall(r"^solving P=\? \[ F<=60 x=50 \]: (\d+) of 60 steps, \d+ s$",
                       told.stderr, flags=re.MULTILINE)
    assert [int(s) for s in steps] == list(range(1, 61))
    # At least 50 heads in 60 fair tosses.
    exact = sum(Fraction(math.comb(60, i), 2**60) for i in range(50, 61))
    low, high = json.loads(told.stdout)["results"][0]["bounds"]
    assert Fraction(low) <= exact <= Fraction(high) and high - low < 1e-12


def test_an_mdp_check_tells_its_stages_on_a_pipe(tmp_path: Path) -> None:
    model = tmp_path / "choice.nm"
    model.write_text("mdp\nmodule m\n s : [0..2] init 0;\n [a] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);\n"
                     " [b] s=0 -> (s'=2);\n [] s>0 -> true;\nendmodule\n")
    for exact in ((), ("--exact",)):
        told = _piped(_EVERY, "prism", str(model), "--property", "Pmax=? [ F s=1 ]",
                      "--property", "Pmin=? [ F s=1 ]", *exact)
        stages = [line for line in told.stderr.splitlines()
                  if not line.startswith(("exploring", "solving"))]
        assert stages == ["building the state space",
                          "checking property 1 of 2: Pmax=? [ F s=1 ]",
                          "checking property 2 of 2: Pmin=? [ F s=1 ]"], exact
        assert re.search(r"Pmax=\? \[ F s=1 \]\s+(0\.5|1/2)\b", told.stdout)
        assert re.search(r"Pmin=\? \[ F s=1 \]\s+0\b", told.stdout)


def test_synthesize_tells_each_weighted_solve_of_its_front() -> None:
    told = _piped(_EVERY, "synthesize", CASE1, *SYNTHESIS, "--require", "0.9", "--format",
                  "json")
    solves = [int(n) for n in re.findall(r"^solving: weighted solve (\d+), \d+ s$",
                                         told.stderr, flags=re.MULTILINE)]
    document = json.loads(told.stdout)
    (answer,) = document["fastest"]
    assert solves == list(range(1, answer["weighted_solves"] + 1)) and len(solves) >= 2
    assert "the fastest strategy per requirement (weighted sums)" in told.stderr


def test_a_count_without_a_total_is_told_as_such() -> None:
    assert progress.solve_text("", 3, 0, "weighted solve", 12.4) == (
        "solving: weighted solve 3, 12 s")
    assert progress.solve_text("P=? [ F a ]", 3, 9, "steps", 1.0) == (
        "solving P=? [ F a ]: 3 of 9 steps, 1 s")


def test_an_mdp_solve_tells_its_levels_and_keeps_its_values(tmp_path: Path) -> None:
    model = tmp_path / "ladder.nm"
    model.write_text("mdp\nmodule m\n s : [0..31] init 0;\n"
                     " [up] s<30 -> 0.9:(s'=s+1) + 0.1:(s'=31);\n"
                     " [risky] s<30 -> 0.5:(s'=s+1) + 0.5:(s'=31);\n [] s>=30 -> true;\n"
                     "endmodule\n")
    args = ("prism", str(model), "--property", "Pmax=? [ F s=30 ]", "--json")
    quiet, told = _piped({}, *args), _piped(_EVERY, *args)
    levels = re.findall(r"^solving Pmax=\? \[ F s=30 \]: (\d+) of (\d+) levels, \d+ s$",
                        told.stderr, flags=re.MULTILINE)
    assert levels and [int(done) for done, _ in levels] == list(range(1, len(levels) + 1))
    assert {int(total) for _, total in levels} == {len(levels)}
    assert json.loads(told.stdout)["results"] == json.loads(quiet.stdout)["results"]
    low, high = json.loads(quiet.stdout)["results"][0]["bounds"]
    assert Fraction(low) <= Fraction(9, 10) ** 30 <= Fraction(high)


def test_distribution_tells_its_reward_levels_and_keeps_its_json(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The level pass of ``distribution`` (11 s of the paper's case) was silent."""
    quiet, told, lines = _quiet_then_told(monkeypatch, "distribution")
    assert "computing the distribution of 'mt'" in lines
    levels = [int(m.group(1).replace(",", "")) for m in
              (re.match(r"solving: reward level ([\d,]+), \d+ s$", line) for line in lines)
              if m is not None]
    # One line per level here (every report is a line), up to the distribution's last.
    document = json.loads(told.stdout)
    assert levels == list(range(1, document["levels"] + 1)) and document["levels"] > 10
    assert document == json.loads(quiet.stdout)


def _quiet_then_told(monkeypatch: pytest.MonkeyPatch, command: str
                     ) -> tuple[Result, Result, list[str]]:
    """*command* on the small case1 farm in JSON, silent with the default intervals,
    then telling every report; both succeed, and the told run's stderr lines begin
    with the build."""
    base = [command, CASE1, *SMALL, "--format", "json"]
    quiet = CliRunner().invoke(cli, base)
    monkeypatch.setenv(progress.INTERVALS_VARIABLE, "0,0")
    told = CliRunner().invoke(cli, base)
    assert quiet.exit_code == told.exit_code == 0 and quiet.stderr == ""
    lines = told.stderr.splitlines()
    assert lines[0] == "building the state space"
    return quiet, told, lines
