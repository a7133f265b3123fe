"""`veribattery sweep` through CliRunner: outputs, files, exit codes, nothing written on error."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest

from tests.sweep.helpers import TWO_POINTS, run

SMALL_FARM = ("--set", "farm.cols=3", "--set", "farm.rows=3", "--set", "farm.base=[0,0]")


def test_json_with_csv_file_and_plot(config: str, tmp_path: Path) -> None:
    out, png = tmp_path / "sweep.csv", tmp_path / "sweep.png"
    result = run("sweep", config, *TWO_POINTS, *SMALL_FARM, "--format", "json",
                 "-o", str(out), "--plot", str(png), "--plot-property", "exp_recharges")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["axes"] == ["battery.capacity_ah"]
    assert len(doc["results"]) == 2 * 5  # points x default properties (2 conditional)
    first = doc["results"][0]
    assert first["battery.capacity_ah"] == 10 and first["property"] == "p_success"
    assert first["holds"] is None
    with out.open() as stream:
        rows = list(csv.DictReader(stream))
    assert [r["property"] for r in rows[:3]] == ["p_success", "exp_mission_time", "exp_recharges"]
    assert [float(r["value"]) for r in rows] == [r["value"] for r in doc["results"]]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 1000


def test_csv_and_failing_requirement_exits_1(config: str) -> None:
    result = run("sweep", config, "--vary", "battery.capacity_ah=10", *SMALL_FARM,
                 "--set", 'requirements=["exp_recharges < 10"]', "--format", "csv")
    assert result.exit_code == 1, result.output
    rows = list(csv.DictReader(io.StringIO(result.stdout)))
    assert rows[0].keys() >= {"point", "battery.capacity_ah", "property", "value", "states",
                              "transitions", "seconds", "requirement", "holds"}
    failing = [r for r in rows if r["holds"]]
    assert [(r["property"], r["holds"]) for r in failing] == [("exp_recharges", "false")]


def test_table_one_row_per_point(config: str) -> None:
    result = run("sweep", config, "--vary", "battery.capacity_ah=10.5", *SMALL_FARM,
                 "--set", 'requirements=["exp_recharges < 10"]')
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert max(map(len, lines)) <= 80  # piped: folded to $COLUMNS (80), never cut
    blocks = [block.splitlines() for block in result.stdout.split("\n\n")]
    headers = " ".join(block[0] for block in blocks)
    for column in ("battery.capacity_ah", "states", "p_success", "exp_recharges",
                   "exp_mission_time_given_success", "requirements"):
        assert column in headers.split()
    assert all(block[2].startswith("10.5 ") for block in blocks)  # the point's key repeated
    assert "PASS" in result.stdout


@pytest.mark.parametrize(
    "args",
    [
        ("--vary", "battery.capacity_ah=10:12"),
        ("--vary", "battery.capacty_ah=10:12:1"),
        ("--vary", "strategy.safe_t=0.3,1.5"),  # invalid at a point: found before checking
        ("--vary", "strategy.safe_t=0.3", "--plot-x", "battery.model"),
        ("--vary", "strategy.safe_t=0.3", "--set", "nope=1"),
        # a property the model cannot resolve: bad input, not a failure of every point
        ("--vary", "strategy.safe_t=0.3", "--set", 'properties.x=P=? [ F "nosuch" ]'),
        ("--vary", "properties.x=a,b"),
        # nesting beyond PyYAML's recursion: one line, not a RecursionError
        ("--vary", "battery.capacity_ah=" + "[" * 3000),
    ],
    ids=["range", "key", "point", "plot-x", "set", "property", "varied-property", "nesting"],
)
def test_bad_input_exits_2_and_writes_nothing(
    config: str, tmp_path: Path, args: tuple[str, ...]
) -> None:
    out, png = tmp_path / "out.csv", tmp_path / "out.png"
    result = run("sweep", config, *args, *SMALL_FARM, "-o", str(out), "--plot", str(png))
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1
    assert not out.exists() and not png.exists()


def test_unsupported_plot_type_and_missing_vary(config: str, tmp_path: Path) -> None:
    result = run("sweep", config, *TWO_POINTS, "--plot", str(tmp_path / "x.txt"))
    assert result.exit_code == 2
    assert "unsupported file type" in result.stderr
    result = run("sweep", config)
    assert result.exit_code == 2
    assert "--vary" in result.stderr


def test_a_failed_point_leaves_no_nan_column(config: str) -> None:
    """The failed point's row has no property: the table has no column named 'nan'."""
    result = run("sweep", config, *SMALL_FARM, "--vary",
                 """properties.x='P=? [ F "success" ]','P=? [ F pow(b,-1)=0 ]'""")
    assert result.exit_code == 1, result.output
    header = result.stdout.splitlines()[0].split()
    assert header == ["properties.x", "states", "transitions", "x"]
    assert "nan" not in result.stdout.lower()
    assert "1 failed" in result.stderr
