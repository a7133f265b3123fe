"""What a new user's first commands show in an 80-column terminal: the whole help when
no command is given (not an error with its middle cut out)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.cli.terminal import run_in_terminal

COMMANDS = ("check", "distribution", "emit", "explain", "phm", "prism", "recheck", "report",
            "reproduce", "simulate", "sweep", "synthesize")


def test_no_command_shows_the_whole_help(tmp_path: Path) -> None:
    screen = run_in_terminal([], 80, tmp_path)
    assert screen.status == 0
    assert "error" not in screen.text and "characters)" not in screen.text
    assert "Options:" in screen.text and "--version" in screen.text
    listed = {line.split()[0] for line in screen.lines if line.startswith("  ") and line.split()}
    assert set(COMMANDS) <= listed
    assert screen.widest <= 80


@pytest.mark.parametrize(("group", "subcommands"),
                         [("phm", ("fade", "forecast", "levels", "simulate"))])
def test_a_group_without_its_subcommand_shows_its_help(
        tmp_path: Path, group: str, subcommands: tuple[str, ...]) -> None:
    screen = run_in_terminal([group], 80, tmp_path)
    assert screen.status == 0
    assert "error" not in screen.text
    for name in subcommands:
        assert any(line.split()[:1] == [name] for line in screen.lines)
