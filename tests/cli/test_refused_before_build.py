"""A property the engine cannot check is refused before the model is built.

Each model below has an update out of its variable's range, so building it fails: a
refusal that names the property proves the property was judged first (before, these
refusals came after the build and its spinner). Checking a whole properties file of an
MDP skips the long-run and conditional properties with a warning and checks the rest,
as the file's unsupported properties are skipped on a DTMC.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.cli import cli

BROKEN = """{kind}
module m
 s : [0..2] init 0;
 [a] s=0 -> 0.5:(s'=1) + 0.5:(s'=5);
 [b] s=0 -> (s'=1);
 [] s>0 -> true;
endmodule
rewards "r" s=1 : 1; endrewards
"""

LONG_RUN = "long-run operators (S, and R [ S ]) are not supported on MDPs"
CONDITIONAL = "conditional probabilities (Storm's 'path || F condition') are not supported"
NOT_COSAFE = "the path of an R operator must be co-safe LTL"
NO_EXACT_MULTI = "multi(...) has no exact MDP kernel"


def _run(tmp_path: Path, kind: str, *args: str) -> tuple[int, list[str]]:
    model = tmp_path / "m.prism"
    model.write_text(BROKEN.format(kind=kind))
    result = CliRunner().invoke(cli, ["prism", str(model), *args])
    return result.exit_code, result.output.strip().splitlines()


@pytest.mark.parametrize(("kind", "formula", "exact", "column", "says"), [
    ("mdp", "S=? [ s=1 ]", False, 1, LONG_RUN),
    ("mdp", "S=? [ s=1 ]", True, 1, LONG_RUN),
    ("mdp", 'R{"r"}max=? [ S ]', False, 1, LONG_RUN),
    ("mdp", '1 - R{"r"}max=? [ S ]', False, 5, LONG_RUN),
    ("mdp", "Pmax=? [ F s=1 || F s>0 ]", False, 1, CONDITIONAL),
    ("mdp", 'R{"r"}max=? [ F s=1 || F s>0 ]', False, 15, CONDITIONAL),
    ("mdp", 'R{"r"}max=? [ G s=1 ]', False, 15, NOT_COSAFE),
    ("mdp", 'R{"r"}max=? [ G s=1 ]', True, 15, NOT_COSAFE),
    ("dtmc", 'R{"r"}=? [ (F s=1) & (G s<2) ]', False, 12, NOT_COSAFE),
    ("dtmc", 'R{"r"}=? [ G s=1 ]', True, 12, NOT_COSAFE),
    ("mdp", "multi(Pmax=? [ F s=1 ], P>=0.1 [ F s=2 ])", True, 1, NO_EXACT_MULTI),
])
def test_a_property_the_engine_refuses_is_refused_before_the_build(
        tmp_path: Path, kind: str, formula: str, exact: bool, column: int, says: str) -> None:
    code, lines = _run(tmp_path, kind, "--property", formula, *(["--exact"] if exact else []))
    assert code == 2
    assert lines == [lines[0]] and lines[0].startswith(f"error: <property>:1:{column}: ")
    assert says in lines[0]


def test_the_broken_model_itself_fails_its_build(tmp_path: Path) -> None:
    """(The premise of the tests above: a checkable property meets the build's error.)"""
    code, lines = _run(tmp_path, "mdp", "--property", "Pmax=? [ F s=1 ]")
    assert code == 2 and "update sets s to 5, outside its range 0..2" in lines[-1]


def test_a_whole_file_skips_what_an_mdp_cannot_check_and_checks_the_rest(
        tmp_path: Path) -> None:
    model = tmp_path / "m.prism"
    model.write_text(BROKEN.format(kind="mdp").replace("(s'=5)", "(s'=2)"))
    props = tmp_path / "m.props"
    props.write_text('Pmax=? [ F s=1 ];\nS=? [ s=1 ];\nR{"r"}max=? [ S ];\n'
                     "Pmin=? [ F s=1 || F s>0 ];\nPmin=? [ F s=1 ];\n")
    result = CliRunner().invoke(cli, ["prism", str(model), "--props", str(props), "--json"])
    assert result.exit_code == 0
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning:")]
    assert [w.split(": unsupported property ")[0] for w in warnings] == [
        f"warning: skipped {props}:{line}:1" for line in (2, 3, 4)]
    assert LONG_RUN in warnings[0] and LONG_RUN in warnings[1] and CONDITIONAL in warnings[2]
    values = [r["value"] for r in json.loads(result.stdout)["results"]]
    assert values == [1.0, 0.5]  # b reaches s=1 surely; a only half the time


def test_a_selected_property_of_a_file_is_still_refused(tmp_path: Path) -> None:
    props = tmp_path / "m.props"
    props.write_text('Pmax=? [ F s=1 ];\n"long": S=? [ s=1 ];\n')
    code, lines = _run(tmp_path, "mdp", "--props", str(props), "--property", "long")
    assert code == 2 and lines[0].startswith(f"error: {props}:2:9: ") and LONG_RUN in lines[0]
