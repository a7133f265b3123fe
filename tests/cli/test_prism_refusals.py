"""``veribattery prism`` refuses, in one line and with exit status 2, input it would
otherwise ignore or misread: options --explain does not read, a properties file
with no properties, a constant's misspelt value, a file that never ends."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from tests.cli.refusals import one_error
from veribattery.cli import cli

_MODEL = """dtmc
const int N = 3;
module m
  x : [0..N] init 0;
  [] x<N -> 0.5:(x'=x+1) + 0.5:(x'=x);
  [] x=N -> true;
endmodule
label "goal" = x=N;
"""


def _prism(tmp_path: Path, *args: str, model: str = _MODEL) -> Result:
    path = tmp_path / "m.pm"
    path.write_text(model)
    return CliRunner().invoke(cli, ["prism", str(path), *args])


@pytest.mark.parametrize(("option", "args"), [
    ("--props", ["--props", "p.props"]),
    ("--property", ["--property", 'P=? [ F "goal" ]']),
    ("--exact", ["--exact"]),
])
def test_explain_refuses_the_options_of_a_check(tmp_path: Path, option: str,
                                                args: list[str]) -> None:
    # a properties file that does not parse: --explain refuses before reading it
    (tmp_path / "p.props").write_text('P=? [ F "goal" ];\nP=? [ F "goal"\n')
    args = [str(tmp_path / a) if a == "p.props" else a for a in args]
    line = one_error(_prism(tmp_path, *args, "--explain", "goal"))
    assert line == (f"error: {option}: --explain checks no properties; leave out {option} "
                    "or --explain")


def test_explain_refuses_max_states(tmp_path: Path) -> None:
    line = one_error(_prism(tmp_path, "--max-states", "9", "--explain", "goal"))
    assert line.startswith("error: --max-states: --explain builds the whole model")


@pytest.mark.parametrize("text", ["", "// only a comment\n",
                                  'const int K = 2;\nlabel "l" = true;\n'])
def test_a_properties_file_without_properties_isone_error(tmp_path: Path, text: str) -> None:
    props = tmp_path / "p.props"
    props.write_text(text)
    line = one_error(_prism(tmp_path, "--props", str(props)))
    assert line == (f"error: {props}: no properties in the file; add one, or give "
                    "--property TEXT (selectors= from Python)")


def test_a_properties_file_without_properties_still_serves_property_text(
        tmp_path: Path) -> None:
    props = tmp_path / "p.props"
    props.write_text("const int K = 2;\n")
    result = _prism(tmp_path, "--props", str(props), "--property", "P=? [ F x=K ]")
    assert result.exit_code == 0, result.output
    assert "P=? [ F x=K ]  1" in result.stdout


@pytest.mark.parametrize("value", ["True", "1", "yes"])
def test_a_bool_constant_says_how_to_spell_a_bool(tmp_path: Path, value: str) -> None:
    model = _MODEL.replace("dtmc", "dtmc\nconst bool reset;")
    line = one_error(_prism(tmp_path, "--property", 'P=? [ F "goal" ]',
                           "--const", f"reset={value}", model=model))
    assert line == (f"error: constant 'reset' is a bool, but was given the value '{value}'; "
                    "use true or false")


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero and /dev/urandom")
@pytest.mark.parametrize(("args", "message"), [
    (["/dev/zero", "--property", "P=? [ F true ]"],
     "error: /dev/zero: more than 64 MB; a PRISM model is at most a few MB (one written "
     "state by state, as --export-induced writes, passes 64 MB past ~550,000 states)"),
    (["MODEL", "--props", "/dev/urandom"],
     "error: /dev/urandom: more than 64 MB; a properties file is at most a few kB"),
    (["/dev/zero", "--explain", "goal"],
     "error: /dev/zero: more than 64 MB; a PRISM model is at most a few MB (one written "
     "state by state, as --export-induced writes, passes 64 MB past ~550,000 states)"),
])
def test_a_file_that_never_ends_is_refused_after_64_mb(tmp_path: Path, args: list[str],
                                                       message: str) -> None:
    model = tmp_path / "m.pm"
    model.write_text(_MODEL)
    result = CliRunner().invoke(cli, ["prism", *(str(model) if a == "MODEL" else a
                                                 for a in args)])
    assert one_error(result) == message

