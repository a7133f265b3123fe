"""``explain``, ``simulate`` and ``prism --explain/--simulate`` through click's CliRunner."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from veribattery.analyses.explain import explain_target
from veribattery.analyses.mission_view import DEFAULT_GROUPINGS, MissionView, build_mission
from veribattery.checker import check
from veribattery.cli import cli
from veribattery.config import load_config
from veribattery.lang import parse_property

EXAMPLE = Path(__file__).resolve().parents[2] / "configs" / "example.yaml"
# 2 x 2 cells, a thin safety margin and a small battery: about 10 % of missions fail
# (running out of battery, or cut at 15 recharges); 2,607 states.
SMALL = ("farm.cols=3", "farm.rows=3", "farm.base=[0,0]", "strategy.safe_t=0.1",
         "battery.capacity_ah=6", "battery.max_recharges=15")
SMALL_ARGS = tuple(a for o in SMALL for a in ("--set", o))

LOOP = """dtmc
module M
  x : [0..3] init 0;
  [a] x=0 -> 0.5:(x'=1) + 0.3:(x'=2) + 0.2:(x'=3);
  [b] x=1 -> 0.4:(x'=0) + 0.1:(x'=3) + 0.5:(x'=2);
  [] x>=2 -> true;
endmodule
label "bad" = x=3;
rewards "steps"
  x<2 : 1;
endrewards
"""


def run(*args: str) -> Result:
    return CliRunner().invoke(cli, list(args))


def _one_line_error(result: Result, expected: str) -> None:
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith("error:") and expected in result.stderr
    assert result.stderr.count("\n") == 1 and result.stdout == ""


@pytest.fixture
def loop(tmp_path: Path) -> Path:
    path = tmp_path / "loop.pm"
    path.write_text(LOOP)
    return path


def test_explain_json_breakdown_sums_to_p_failure(tmp_path: Path) -> None:
    paths_csv = tmp_path / "paths.csv"
    # the old name and the new naming one file: taken once (two files are refused)
    result = run("explain", str(EXAMPLE), *SMALL_ARGS, "--top", "2", "--format", "json",
                 "--csv", str(paths_csv), "-o", str(paths_csv))
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    mission = build_mission(load_config(EXAMPLE, SMALL))
    exact = check(mission.dtmc, parse_property('P=? [ F "failure" ]')).value
    assert 0.05 < exact < 0.2
    assert doc["p_failure"] == pytest.approx(exact, abs=1e-12)
    assert set(doc["breakdown"]) == {"+".join(g) for g in DEFAULT_GROUPINGS}
    for records in doc["breakdown"].values():
        assert sum(r["probability"] for r in records) == pytest.approx(exact, abs=1e-9)
    assert len(doc["paths"]) == 2
    assert doc["paths"][0]["probability"] >= doc["paths"][1]["probability"]
    assert doc["paths"][0]["states"][-1]["s"] == 6
    with paths_csv.open() as stream:
        rows = list(csv.DictReader(stream))
    for column in ("path", "probability", "step", "action", "s", "k", "j", "x", "y", "wsp",
                   "b", "rc"):
        assert column in rows[0]
    assert {r["path"] for r in rows} == {"1", "2"}


def test_explain_table_and_joint_grouping() -> None:
    result = run("explain", str(EXAMPLE), *SMALL_ARGS, "--top", "1", "--by", "wind+level,rc")
    assert result.exit_code == 0, result.output
    assert "by wind, level" in result.stdout and "by rc" in result.stdout
    assert "Path 1: probability" in result.stdout


def test_explain_bad_input() -> None:
    _one_line_error(run("explain", str(EXAMPLE), "--top", "0"), "--top must be at least 1")
    _one_line_error(run("explain", str(EXAMPLE), *SMALL_ARGS, "--by", "colour"),
                    "--by colour: no key 'colour'")


def test_paper_story_at_12_8_ah() -> None:
    """The paper's Fig. 7: continue inspecting in high wind, return, cannot pay for the landing."""
    mission = build_mission(load_config(EXAMPLE, ("battery.capacity_ah=12.8",)))
    view = MissionView(mission)
    failure = mission.dtmc.labels["failure"]
    explanation = explain_target(mission.dtmc, failure, name="failure",
                                 describe=view.columns, by=DEFAULT_GROUPINGS, top=1)
    exact = check(mission.dtmc, parse_property('P=? [ F "failure" ]')).value
    assert explanation.probability == pytest.approx(exact, abs=1e-12) and exact > 0.05
    by_action = explanation.groupings[1]
    (state, action), p = by_action.groups[0]
    assert (state, action) == ("above base", "oob (land)") and p > 0.99 * exact
    steps = view.steps(explanation.paths[0].states)
    last = [(s["action"], s["wind"]) for s in steps[-4:-1]]
    assert last[0] == ("inspect", "high")
    assert last[1][0] in ("back", "backnext") and last[1][1] == "high"
    assert last[2][0] == "oob (land)"
    assert steps[-1]["s"] == 6


def test_simulate_json_beside_exact_values() -> None:
    result = run("simulate", str(EXAMPLE), *SMALL_ARGS, "--runs", "4000", "--seed", "5",
                 "--format", "json")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert set(doc["results"]) == {"p_success", "exp_mission_time", "exp_recharges"}
    for entry in doc["results"].values():
        assert entry["runs"] == 4000 and entry["undecided"] == 0
        lo, hi = entry["ci95"]
        assert lo <= entry["estimate"] <= hi
    assert "outside the 99.9" not in result.stderr


def test_simulate_paths_csv_and_bad_input(tmp_path: Path) -> None:
    paths = tmp_path / "runs.csv"
    result = run("simulate", str(EXAMPLE), *SMALL_ARGS, "--runs", "20", "--paths", str(paths),
                 "--path-count", "2")
    assert result.exit_code == 0, result.output
    with paths.open() as stream:
        rows = list(csv.DictReader(stream))
    assert list(rows[0])[:3] == ["run", "action", "step"]
    assert {"s", "k", "j", "wsp", "b", "rc", "mt"} <= set(rows[0])
    assert rows[0]["action"] == "takeoff" and {r["run"] for r in rows} == {"1", "2"}
    _one_line_error(run("simulate", str(EXAMPLE), "--runs", "0"), "--runs must be at least 1")


def test_prism_explain_and_simulate(loop: Path) -> None:
    result = run("prism", str(loop), "--explain", "bad", "--top", "2", "--json")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["p_bad"] == pytest.approx(5 / 16)
    assert doc["breakdown"]["x"] == [{"x": 0, "probability": pytest.approx(0.25)},
                                     {"x": 1, "probability": pytest.approx(0.0625)}]
    assert [p["probability"] for p in doc["paths"]] == pytest.approx([0.2, 0.05])
    assert [s["action"] for s in doc["paths"][1]["states"]] == ["a", "b", ""]
    result = run("prism", str(loop), "--property", 'P=? [ F "bad" ]', "--simulate", "3000",
                 "--json")
    assert result.exit_code == 0, result.output
    (entry,) = json.loads(result.stdout)["results"].values()
    assert entry["value"] == pytest.approx(5 / 16) and entry["runs"] == 3000


def test_prism_bad_input(loop: Path) -> None:
    _one_line_error(run("prism", str(loop), "--explain", "nope"),
                    '--explain "nope": the model has no such label')
    _one_line_error(run("prism", str(loop), "--explain", "bad", "--top", "0"),
                    "--top must be at least 1")
    _one_line_error(run("prism", str(loop), "--property", "P=? [ F x=3 ]", "--simulate", "0"),
                    "--simulate must be at least 1")
    # more runs than any memory holds (numpy cannot even size them past 2^63)
    _one_line_error(run("prism", str(loop), "--property", "P=? [ F x=3 ]", "--simulate",
                        "99999999999999999999"),
                    "--simulate must be at most 1,000,000,000,000, not "
                    "99,999,999,999,999,999,999")
    _one_line_error(run("prism", str(loop), "--property", "P=? [ F x=3 ]", "--simulate", "5",
                        "--seed", "-1"),
                    "Invalid value for '--seed': -1 is not in the range x>=0")
    _one_line_error(run("prism", str(loop), "--property", "P=? [ F x=3 ]", "-o",
                        str(loop.with_suffix(".csv"))),
                    "-o writes the sampled paths of --simulate N: give --simulate")
    assert not loop.with_suffix(".csv").exists()


def test_prism_simulate_reports_undecided_runs(loop: Path) -> None:
    result = run("prism", str(loop), "--property", 'P=? [ F "bad" ]', "--simulate", "50",
                 "--max-steps", "1", "--seed", "2", "--json")
    assert result.exit_code == 0, result.output
    (entry,) = json.loads(result.stdout)["results"].values()
    # After one step only runs at x=1 are undecided (x=2, x=3 decide at once).
    assert entry["runs"] + entry["undecided"] == 50 and entry["undecided"] > 0
    assert "undecided after 1 steps" in result.stderr


@pytest.mark.parametrize("output_format", ["table", "csv"])
def test_simulate_with_every_run_undecided_prints_no_nan(output_format: str) -> None:
    """No run decides within one step: no estimate, shown as '-' (table) or an empty cell
    (csv), as JSON gives null, never 'nan' printed as if it were a value."""
    result = run("simulate", str(EXAMPLE), *SMALL_ARGS, "--runs", "5", "--max-steps", "1",
                 "--format", output_format)
    assert result.exit_code == 0, result.output
    assert "nan" not in result.stdout.lower()
    if output_format == "csv":
        rows = list(csv.DictReader(result.stdout.splitlines()))
        assert {(r["estimate"], r["ci95_low"], r["ci95_high"], r["runs"]) for r in rows} == {
            ("", "", "", "0")}
    else:
        row = result.stdout.splitlines()[2].split()
        assert row[0] == "p_success" and row[2:4] == ["-", "-"]
    assert "5 of 5 runs undecided after 1 steps" in result.stderr
