"""Help texts: every command's summary whole, no paper codes left unexplained."""

from __future__ import annotations

import re

import pytest
from click.testing import CliRunner

from veribattery.cli import cli

COMMANDS = ["check", "emit", "prism", "sweep", "reproduce", "explain", "simulate",
            "distribution", "recheck", "phm", "phm fade", "phm levels", "phm simulate",
            "phm forecast"]
#: The paper's labels for assumptions and strategies (BA1, BS1, EA2, CP1, ...).
PAPER_CODE = re.compile(r"\b(BA|BS|EA|CP)[0-9]\b")


def _help(words: list[str]) -> str:
    result = CliRunner().invoke(cli, [*words, "--help"], terminal_width=80)
    assert result.exit_code == 0, result.output
    return result.stdout


def test_the_command_list_shows_whole_summaries() -> None:
    for text in (_help([]), _help(["phm"])):
        listed = text.split("Commands:")[1].splitlines()
        assert listed and not [line for line in listed if line.rstrip().endswith("...")]


@pytest.mark.parametrize("command", COMMANDS)
def test_help_fits_80_columns_and_explains_its_terms(command: str) -> None:
    text = _help(command.split())
    assert max(map(len, text.splitlines())) <= 80
    for match in PAPER_CODE.finditer(text):
        nearby = text[max(0, match.start() - 60): match.end() + 60]
        assert "assumption" in nearby or "strategy" in nearby, nearby
