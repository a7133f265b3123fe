"""The command line through click's CliRunner: output contracts, exit codes, bad input."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from veribattery.cli import cli

DIE = """dtmc
module die
  s : [0..7] init 0;
  d : [0..6] init 0;
  [] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);
  [] s=1 -> 0.5:(s'=3) + 0.5:(s'=4);
  [] s=2 -> 0.5:(s'=5) + 0.5:(s'=6);
  [] s=3 -> 0.5:(s'=1) + 0.5:(s'=7) & (d'=1);
  [] s=4 -> 0.5:(s'=7) & (d'=2) + 0.5:(s'=7) & (d'=3);
  [] s=5 -> 0.5:(s'=7) & (d'=4) + 0.5:(s'=7) & (d'=5);
  [] s=6 -> 0.5:(s'=2) + 0.5:(s'=7) & (d'=6);
  [] s=7 -> (s'=7);
endmodule
label "six" = s=7 & d=6;
rewards "flips"
  s<7 : 1;
endrewards
"""

SMALL_FARM = ("--set", "farm.cols=3", "--set", "farm.rows=3", "--set", "farm.base=[0,0]")


def run(*args: str) -> Result:
    return CliRunner().invoke(cli, list(args))


@pytest.fixture
def baseline(tmp_path: Path) -> str:
    """An empty config file: the paper's baseline."""
    path = tmp_path / "baseline.yaml"
    path.write_text("")
    return str(path)


@pytest.fixture
def die(tmp_path: Path) -> Path:
    path = tmp_path / "die.pm"
    path.write_text(DIE)
    (tmp_path / "die.props").write_text('"six": P=? [ F "six" ];\nR{"flips"}=? [ F s=7 ];\n')
    return path


def test_prism_json_contract(die: Path) -> None:
    result = run("prism", str(die), "--props", str(die.with_suffix(".props")), "--json")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert set(doc) == {"model", "results", "timings_s"}
    # the one state where both properties are decided ("six", s=7) is left unexpanded
    assert doc["model"] == {"states": 13, "transitions": 20, "initial_states": 1, "deadlocks": 0,
                            "stopped_states": 1}
    assert [r["property"] for r in doc["results"]] == ['P=? [ F "six" ]', 'R{"flips"}=? [ F s=7 ]']
    assert [r.get("name") for r in doc["results"]] == ["six", None]
    assert doc["results"][0]["value"] == pytest.approx(1 / 6, rel=1e-12)
    assert doc["results"][1]["value"] == pytest.approx(11 / 3, rel=1e-12)
    assert set(doc["timings_s"]) == {"parse", "build", "check"}
    whole = run("prism", str(die), "--props", str(die.with_suffix(".props")), "--json",
                "--all-states")
    assert json.loads(whole.stdout)["model"] == {"states": 13, "transitions": 20,
                                                 "initial_states": 1, "deadlocks": 0}


def test_prism_selects_by_index_name_and_text(die: Path) -> None:
    props = str(die.with_suffix(".props"))
    for selector in ("1", "six", 'P=? [ F "six" ]'):
        result = run("prism", str(die), "--props", props, "--property", selector, "--json")
        doc = json.loads(result.stdout)
        assert [r["value"] for r in doc["results"]] == [pytest.approx(1 / 6, rel=1e-12)]


def test_prism_table_output(die: Path) -> None:
    result = run("prism", str(die), "--property", 'P=? [ F "six" ]')
    assert result.exit_code == 0
    assert "13 states, 20 transitions" in result.stdout
    assert "0.166666666667" in result.stdout


def test_prism_infinity_is_strict_json(die: Path) -> None:
    result = run("prism", str(die), "--property", "R=? [ F d=9 ]", "--json")
    assert json.loads(result.stdout)["results"][0]["value"] == "Infinity"


@pytest.mark.parametrize(
    ("model_text", "args", "expected"),
    [
        ("dtmc\nmodule m\n  x : [0..1] init 0;\n  [] x=0 -> (x'=1)\nendmodule\n", (),
         "model.pm:5:1: unexpected token 'endmodule'"),
        ("dtmc\nconst int N;\nmodule m\n  x : [0..N] init 0;\n  [] true -> (x'=0);\nendmodule\n",
         (), "undefined constant N"),
        ("dtmc\nconst int N;\nmodule m\n  x : [0..N] init 0;\n  [] true -> (x'=0);\nendmodule\n",
         ("--const", "N"), "N"),
        ("dtmc\nmodule m\n  x : [0..1] init 0;\n  [] true -> (x'=y);\nendmodule\n", (),
         "model.pm:4:18: unknown identifier 'y'"),
        # (x=1 decides the property: the update out of range is met past it)
        ("dtmc\nmodule m\n  x : [0..1] init 0;\n  [] true -> (x'=x+1);\nendmodule\n",
         ("--all-states",), "x"),
    ],
    ids=["syntax", "undefined-const", "malformed-const", "unknown-identifier", "out-of-range"],
)
def test_prism_bad_model_exits_2_with_one_line(
    tmp_path: Path, model_text: str, args: tuple[str, ...], expected: str
) -> None:
    model = tmp_path / "model.pm"
    model.write_text(model_text)
    result = run("prism", str(model), "--property", "P=? [ F x=1 ]", *args)
    assert result.exit_code == 2
    assert expected in result.stderr
    assert "Traceback" not in result.output
    assert result.stderr.startswith("error:")


@pytest.mark.parametrize(
    ("prop", "expected"),
    [('P=? [ F "nope" ]', "unknown label"), ('R{"nope"}=? [ F s=7 ]', "nope")],
    ids=["unknown-label", "unknown-reward"],
)
def test_prism_bad_property_exits_2(die: Path, prop: str, expected: str) -> None:
    result = run("prism", str(die), "--property", prop)
    assert result.exit_code == 2
    assert expected in result.stderr


def test_prism_missing_file_exits_2(tmp_path: Path) -> None:
    result = run("prism", str(tmp_path / "absent.pm"), "--property", "P=? [ F true ]")
    assert result.exit_code == 2
    assert "absent.pm" in result.stderr


def test_check_json_contract_on_a_small_farm(tmp_path: Path) -> None:
    config = tmp_path / "mission.yaml"
    config.write_text("requirements: ['p_success >= 0.5']\n")
    result = run("check", str(config), *SMALL_FARM, "--format", "json")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert set(doc) == {"model", "results", "bounds", "precise", "conditional", "requirements",
                        "timings_s", "recharge_cap_probability"}
    assert doc["conditional"] == ["exp_mission_time_given_success", "exp_recharges_given_success"]
    assert set(doc["results"]) == {"p_success", "exp_mission_time", "exp_recharges",
                                   "exp_mission_time_given_success", "exp_recharges_given_success"}
    assert doc["requirements"][0]["holds"] is True
    assert doc["requirements"][0]["decided"] is True
    assert doc["results"]["p_success"] == pytest.approx(1.0, abs=1e-12)
    for name, value in doc["results"].items():
        lower, upper = (math.inf if end == "Infinity" else end for end in doc["bounds"][name])
        assert lower <= value <= upper
        # Conditional results are certified too (ratio of certified quantities).
        assert doc["precise"][name] is True


def test_check_failing_requirement_exits_1(tmp_path: Path) -> None:
    config = tmp_path / "mission.yaml"
    config.write_text("requirements: ['exp_recharges <= 0.5']\n")
    result = run("check", str(config), *SMALL_FARM)
    assert result.exit_code == 1
    assert "FAIL" in result.stdout


def test_check_csv_says_on_stderr_which_requirement_fails(tmp_path: Path) -> None:
    config = tmp_path / "mission.yaml"
    config.write_text("requirements: ['exp_recharges <= 0.5', 'p_success >= 0.5']\n")
    result = run("check", str(config), *SMALL_FARM, "--format", "csv")
    assert result.exit_code == 1
    assert "FAIL" not in result.stdout  # stdout stays CSV
    [line] = [line for line in result.stderr.splitlines() if "FAIL" in line]
    assert line.startswith("FAIL exp_recharges <= 0.5 (value ")


def test_check_csv(baseline: str) -> None:
    result = run("check", baseline, *SMALL_FARM, "--format", "csv")
    lines = result.stdout.splitlines()
    assert lines[0] == "property,value"
    assert [line.split(",")[0] for line in lines[1:]] == [
        "p_success", "exp_mission_time", "exp_recharges", "exp_mission_time_given_success",
        "exp_recharges_given_success", "recharge_cap_probability"]


@pytest.mark.parametrize(
    ("yaml_text", "sets", "expected"),
    [
        ("strategy:\n  safe_t: 1.5\n", (), "strategy.safe_t"),
        ("battery:\n  capacity: 11\n", (), "battery.capacity_ah"),
        ("farm: [1, 2\n", (), "mission.yaml:"),
        ("", ("--set", "farm.base"), "farm.base"),
    ],
    ids=["range", "unknown-key", "yaml-syntax", "malformed-set"],
)
def test_check_bad_config_exits_2_and_writes_nothing(
    tmp_path: Path, yaml_text: str, sets: tuple[str, ...], expected: str
) -> None:
    config = tmp_path / "mission.yaml"
    config.write_text(yaml_text)
    out = tmp_path / "out"
    result = run("check", str(config), *sets, "--emit", str(out))
    assert result.exit_code == 2
    assert expected in result.stderr
    assert "Traceback" not in result.output
    assert not out.exists()


def test_check_emit_lists_the_files_it_wrote_on_stderr(tmp_path: Path, baseline: str) -> None:
    out = tmp_path / "out"
    result = run("check", baseline, *SMALL_FARM, "--emit", str(out))
    assert result.exit_code == 0
    wrote = [line for line in result.stderr.splitlines() if line.startswith("wrote ")]
    assert sorted(wrote) == sorted(f"wrote {path}" for path in out.iterdir())
    assert len(wrote) == 4 and "wrote" not in result.stdout


def test_emit_writes_four_files_and_never_overwrites(tmp_path: Path, baseline: str) -> None:
    out = tmp_path / "emitted"
    result = run("emit", baseline, *SMALL_FARM, "-o", str(out))
    assert result.exit_code == 0, result.output
    names = sorted(p.name for p in out.iterdir())
    assert names == ["config.resolved.yaml", "model.prism", "properties.props",
                     "storm-only.props"]
    before = (out / "model.prism").read_text()
    again = run("emit", baseline, "-o", str(out))
    assert again.exit_code == 2
    assert "already exist" in again.stderr
    assert (out / "model.prism").read_text() == before
    assert run("emit", baseline, "-o", str(out), "--force").exit_code == 0


def test_emitted_files_check_like_the_config(tmp_path: Path, baseline: str) -> None:
    out = tmp_path / "emitted"
    run("emit", baseline, *SMALL_FARM, "-o", str(out))
    direct = json.loads(run("check", baseline, *SMALL_FARM, "--format", "json").stdout)
    values = {}
    for props in ("properties.props", "storm-only.props"):
        via_file = json.loads(run(
            "prism", str(out / "model.prism"), "--props", str(out / props), "--json"
        ).stdout)
        assert via_file["model"]["states"] == direct["model"]["states"]
        values |= {r["name"]: r["value"] for r in via_file["results"]}
    assert values == direct["results"]  # the two files hold every property between them
    resolved = json.loads(run(
        "check", str(out / "config.resolved.yaml"), "--format", "json").stdout)
    assert resolved["results"] == direct["results"]


@pytest.fixture
def coin(tmp_path: Path) -> Path:
    model = tmp_path / "coin.pm"
    model.write_text("dtmc\nconst double p;\nconst int N;\nmodule m\n  x : [0..9] init 0;\n"
                     "  [] x<N -> p:(x'=x+1) + 1-p:(x'=N);\nendmodule\n")
    return model


def test_prism_const_may_be_an_expression(coin: Path) -> None:
    """``--const p=1/3`` is the double nearest 1/3 (and 1/3 itself under --exact)."""
    model = coin
    prop = ("--property", "P=? [ F x=2 ]")
    given = run("prism", str(model), *prop, "--const", "p=1/3,N=2*3", "--json")
    assert given.exit_code == 0, given.output
    written = run("prism", str(model), *prop, "--const", f"p={1 / 3!r}", "--const", "N=6",
                  "--json")
    assert json.loads(given.stdout)["results"] == json.loads(written.stdout)["results"]
    exact = run("prism", str(model), *prop, "--const", "p=1/3,N=max(2,3)*2", "--exact",
                "--json")
    assert exact.exit_code == 0, exact.output
    assert json.loads(exact.stdout)["results"][0]["exact"] == "1/9"


def test_prism_const_expression_with_a_name_is_rejected(coin: Path) -> None:
    result = run("prism", str(coin), "--property", "P=? [ F x=2 ]", "--const", "p=0.5,N=2*x")
    assert result.exit_code == 2
    assert result.stderr == "error: constant 'N' is an int, but was given the value '2*x'\n"


def test_prism_unknown_const_name_is_rejected(die: Path) -> None:
    result = run("prism", str(die), "--property", 'P=? [ F "six" ]', "--const", "Y=3")
    assert result.exit_code == 2
    assert result.stderr == (
        "error: constant Y: declared neither in the model nor in its properties, but given a "
        "value (by --const, or constants= from Python); the undefined constants are: none\n")


def test_error_text_with_brackets_is_printed_verbatim(tmp_path: Path) -> None:
    model = tmp_path / "model.pm"
    model.write_text("dtmc\nmodule m\n  x : [0..1] init 0;\n  [go] x=0 -> (x'=2);\nendmodule\n")
    result = run("prism", str(model), "--property", "P=? [ F x=1 ]")
    assert result.exit_code == 2
    assert result.stderr.count("\n") == 1
    assert "model.pm:4:3: module m, command [go]: update sets x to 2, outside its range 0..1, " \
        "in state (x=0)" in result.stderr


def test_syntax_error_is_one_line_off_a_terminal(tmp_path: Path) -> None:
    model = tmp_path / "model.pm"
    model.write_text("dtmc\nmodule m\n  x : [0..1] init 0;\n  [] x=0 -> (x'=1)\nendmodule\n")
    result = run("prism", str(model), "--property", "P=? [ F x=1 ]")
    assert result.stderr.count("\n") == 1


def test_whole_file_skips_unsupported_properties_with_a_warning(die: Path) -> None:
    props = die.with_name("mixed.props")
    props.write_text('P=? [ F "six" ];\nP=? [ F<=3 G s=7 ];\nR{"flips"}=? [ F s=7 ];\n')
    result = run("prism", str(die), "--props", str(props), "--json")
    assert result.exit_code == 0, result.output
    values = [r["value"] for r in json.loads(result.stdout)["results"]]
    assert values == [pytest.approx(1 / 6, rel=1e-12), pytest.approx(11 / 3, rel=1e-12)]
    assert "mixed.props:2:1: unsupported property P=? [ F<=3 G s=7 ]" in result.stderr
    picked = run("prism", str(die), "--props", str(props), "--property", "2")
    assert picked.exit_code == 2
    assert "unsupported property" in picked.stderr
