"""``veribattery prism MODEL --explain LABEL`` as a user reads it: the headline's
count of entering states in good English, at 80 columns in a terminal too."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.cli.terminal import run_in_terminal
from veribattery.cli import cli

#: "goal" is entered from x=2 only (one state), or from x=1 and x=2 (FORK: two).
_ONE = """dtmc
module m
  x : [0..3] init 0;
  [] x<3 -> 0.5:(x'=x+1) + 0.5:(x'=x);
  [] x=3 -> true;
endmodule
label "goal" = x=3;
"""
_FORK = """dtmc
module m
  x : [0..3] init 0;
  [] x=0 -> 0.5:(x'=1) + 0.5:(x'=2);
  [] x=1 | x=2 -> (x'=3);
  [] x=3 -> true;
endmodule
label "goal" = x=3;
"""


@pytest.mark.parametrize(("model", "words"), [(_ONE, "the 1 state goal"),
                                               (_FORK, "the 2 states goal")])
def test_the_headline_counts_entering_states_in_english(tmp_path: Path, model: str,
                                                        words: str) -> None:
    path = tmp_path / "m.pm"
    path.write_text(model)
    result = CliRunner().invoke(cli, ["prism", str(path), "--explain", "goal"])
    assert result.exit_code == 0, result.output
    headline = " ".join(result.stdout.split("\n\n")[0].split())
    assert headline == (f"P(goal) = 1 (exact; the breakdown sums to it over {words} is "
                        "entered from)")


def test_explain_reads_well_at_80_columns(tmp_path: Path) -> None:
    (tmp_path / "m.pm").write_text(_ONE)
    screen = run_in_terminal(["prism", "m.pm", "--explain", "goal"], 80, tmp_path)
    assert screen.status == 0, screen.text
    assert screen.widest <= 80, screen.text
    assert "over the 1 state goal is" in screen.text, screen.text
    screen = run_in_terminal(["prism", "m.pm", "--explain", "goal", "--exact"], 80, tmp_path)
    assert screen.status == 2, screen.text
    assert " ".join(screen.text.split()) == (
        "error: --exact: --explain checks no properties; leave out --exact or --explain")
