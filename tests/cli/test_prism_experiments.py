"""``veribattery prism --const N=a:b``: PRISM's experiments, one check per point."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.checker.test_exact import KNUTH_DIE
from veribattery.cli import cli
from veribattery.errors import PrismSemanticError
from veribattery.lang.experiments import constant_points


def test_ranges_expand_exactly_and_combine_first_slowest() -> None:
    assert constant_points({"p": "0.1:0.1:0.3", "N": "2:3", "k": "7"}) == [
        {"p": "0.1", "N": "2", "k": "7"}, {"p": "0.1", "N": "3", "k": "7"},
        {"p": "0.2", "N": "2", "k": "7"}, {"p": "0.2", "N": "3", "k": "7"},
        {"p": "0.3", "N": "2", "k": "7"}, {"p": "0.3", "N": "3", "k": "7"}]
    # steps that no decimal writes are kept as fractions, not rounded (0.333...)
    assert [p["q"] for p in constant_points({"q": "0:1/3:1"})] == ["0", "1/3", "2/3", "1"]
    assert [p["n"] for p in constant_points({"n": "5:-2:0"})] == ["5", "3", "1"]


@pytest.mark.parametrize(("value", "message"), [
    ("2:0:4", "never reaches"), ("4:2", "never reaches"), ("a:b", "start:end"),
    ("1:2:3:4", "start:end"), ("1:100000", "at most 10,000")])
def test_a_bad_range_is_named(value: str, message: str) -> None:
    with pytest.raises(PrismSemanticError, match=message):
        constant_points({"N": value})


def _run(tmp_path: Path, model: str, *args: str) -> tuple[int, str, str]:
    path = tmp_path / "m.prism"
    path.write_text(model)
    result = CliRunner().invoke(cli, ["prism", str(path), *args])
    return result.exit_code, result.stdout, result.stderr


# Knuth's die: each face has probability 1/6.
_DIE_PROPS = ["--property", "P=? [ F s=7 & d=x ]", "--property", "P>1/7 [ F s=7 & d>=x ]"]


def test_an_experiment_checks_every_point(tmp_path: Path) -> None:
    code, out, err = _run(tmp_path, KNUTH_DIE.replace("module die", "const int x;\nmodule die"),
                          *_DIE_PROPS, "--const", "x=1:6", "--json", "--exact")
    assert code == 0, err
    points = json.loads(out)["points"]
    assert [p["constants"] for p in points] == [{"x": str(x)} for x in range(1, 7)]
    assert [p["results"][0]["exact"] for p in points] == ["1/6"] * 6
    # P(d >= x) = (7 - x)/6 > 1/7 for every x up to 6
    assert [p["results"][1]["value"] for p in points] == [True] * 6


def test_the_table_and_csv_lead_with_the_varying_constants(tmp_path: Path) -> None:
    model = KNUTH_DIE.replace("module die", "const int x;\nconst int y;\nmodule die")
    code, out, _ = _run(tmp_path, model, *_DIE_PROPS[:2], "--const", "x=2:3,y=0")
    assert code == 0
    assert out.splitlines()[0].split() == ["x", "property", "value"]
    assert "2 points; models of 13 states" in out
    code, out, _ = _run(tmp_path, model, *_DIE_PROPS[:2], "--const", "x=2:3,y=0",
                        "--format", "csv")
    rows = list(csv.reader(io.StringIO(out)))
    assert rows[0] == ["x", "property", "name", "value", "lower", "upper", "exact"]
    assert [r[0] for r in rows[1:]] == ["2", "3"]


def test_an_mdp_experiment(tmp_path: Path) -> None:
    model = ("mdp\nconst int N;\nmodule m\n  x : [0..10];\n  [a] x<N -> (x'=x+1);\n"
             "  [b] x<N -> 0.5:(x'=x+1) + 0.5:(x'=0);\nendmodule\n")
    code, out, err = _run(tmp_path, model, "--property", "Pmin=? [ F<=N x=N ]",
                          "--const", "N=1:3", "--json")
    assert code == 0, err
    # the worst strategy flips a coin at each step: (1/2)^N within N steps
    assert [p["results"][0]["value"] for p in json.loads(out)["points"]] == [0.5, 0.25, 0.125]


def test_options_that_read_one_model_are_refused_before_any_work(tmp_path: Path) -> None:
    model = KNUTH_DIE.replace("module die", "const int x;\nmodule die")
    code, out, err = _run(tmp_path, model, *_DIE_PROPS[:2], "--const", "x=1:6",
                          "--simulate", "10")
    assert code == 2 and out == "" and "--simulate reads one model" in err


# Deadlocks in the last M states: a warning at every point of an experiment over N.
_DEADLOCKS = """dtmc
const int N;
const int M = 1;
module m
  x : [0..N] init 0;
  [] x<N-M -> 0.5:(x'=x+1) + 0.5:(x'=x);
endmodule
label "goal" = x=N;
"""


@pytest.mark.parametrize("output_format", ["table", "json", "csv"])
def test_an_experiment_says_which_point_each_warning_is_of(tmp_path: Path,
                                                           output_format: str) -> None:
    code, _, err = _run(tmp_path, _DEADLOCKS, "--property", 'P=? [ F "goal" ]',
                        "--const", "N=2:2:6", "--format", output_format)
    assert code == 0, err
    assert [line.split(": ")[:2] for line in err.splitlines()] == [
        ["warning", f"N={n}"] for n in (2, 4, 6)]


def test_one_point_warns_as_one_run_does(tmp_path: Path) -> None:
    code, _, err = _run(tmp_path, _DEADLOCKS, "--property", 'P=? [ F "goal" ]',
                        "--const", "N=2:2:3")
    assert code == 0, err
    assert err.startswith("warning: 1 deadlock state")
