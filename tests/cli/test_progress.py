"""Build progress on stderr when it is not a terminal, and ``--max-states``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.cli.inputs import CASE1, SMALL
from veribattery.cli import cli, progress

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
