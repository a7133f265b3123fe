"""`veribattery sweep` options of issue 6: -j, -o RESULTS, resume, sweep: section, bad input."""

from __future__ import annotations

import csv
import json
import os
import re
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.sweep.helpers import PER_POINT, TWO_POINTS, run
from tests.sweep.helpers import SMALL_FARM as TINY

SMALL_FARM = tuple(arg for item in TINY for arg in ("--set", item))


def test_results_resume_and_plain_progress_lines(config: str, tmp_path: Path) -> None:
    out = tmp_path / "r.csv"
    first = run("sweep", config, *TWO_POINTS, *SMALL_FARM, "-j", "1", "-o", str(out))
    assert first.exit_code == 0, first.output
    lines = first.stderr.splitlines()
    assert "full build at every point; running in this process" in lines
    assert lines[1].startswith("[1/2] battery.capacity_ah=10: p_success=")
    assert lines[2].startswith("[2/2] battery.capacity_ah=10.5: ")
    assert lines[-1] == "2 points: 2 checked, 0 failed"
    with out.open() as stream:
        points = [row["point"] for row in csv.DictReader(stream)]
        assert points == ["0"] * PER_POINT + ["1"] * PER_POINT
    again = run("sweep", config, *TWO_POINTS, *SMALL_FARM, "-o", str(out), "--format", "csv")
    assert again.exit_code == 0, again.output
    assert "2 of 2 points already done" in again.stderr
    assert again.stdout.count("\n") == 1 + 2 * PER_POINT


def test_sweep_section_in_config_and_vary_overrides_it(tmp_path: Path) -> None:
    path = tmp_path / "mission.yaml"
    path.write_text("sweep:\n  vary: ['battery.capacity_ah=10,10.5']\n")
    result = run("sweep", str(path), *SMALL_FARM, "--format", "csv")
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(result.stdout.splitlines()))
    assert [float(row["battery.capacity_ah"]) for row in rows][::PER_POINT] == [10, 10.5]
    result = run("sweep", str(path), *SMALL_FARM, "--vary", "strategy.safe_t=0.3",
                 "--format", "csv")
    assert result.exit_code == 0, result.output
    assert "battery.capacity_ah" not in result.stdout.splitlines()[0]


def test_failed_point_exits_1_with_summary(tmp_path: Path) -> None:
    path = tmp_path / "mission.yaml"
    # The second formula resolves but cannot be evaluated (pow(b,-1) of an int): that point
    # fails; an unknown label would be bad input, refused before any point.
    path.write_text("sweep:\n  vary: ['properties.extra=\"P=? [ F \\\"success\\\" ]\",\"P=? "
                    "[ F pow(b,-1)=0 ]\"']\n")
    result = run("sweep", str(path), *SMALL_FARM, "--format", "csv")
    assert result.exit_code == 1, result.output
    assert result.stderr.splitlines()[-1] == "2 points: 1 checked, 1 failed"
    assert "FAILED: " in result.stderr


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (("--vary", "battery.capacty_ah=10:12:1"), "unknown key"),
        (("--vary", "battery.capacity_ah=10:12"), "START:STOP:STEP"),
        (("--vary", "battery.capacity_ah=12:10:1"), "STOP must be"),
        (("--vary", "battery.capacity_ah=10", "--vary", "battery.capacity_ah=11"),
         "varied more than once"),
        ((), "nothing to sweep"),
        (("--vary", "battery.capacity_ah=10", "-o", "{tmp}/nofolder/r.csv"), "does not exist"),
        (("--vary", "battery.capacity_ah=10", "-o", "{tmp}/r.xlsx"), "unsupported results"),
        (("--vary", "battery.capacity_ah=10", "-o", "{tmp}/mine.csv"), "not the results"),
        (("--vary", "battery.capacity_ah=10", "-o", "{tmp}/ro/r.csv"),
         "cannot write there (read-only"),
        (("--vary", "battery.capacity_ah=10", "-o", "{tmp}/d.csv"),
         "d.csv: is a folder; name a results file (.csv, .jsonl or .parquet) in it"),
    ],
    ids=["key", "spec", "empty", "twice", "none", "folder", "suffix", "not-ours", "read-only",
         "is-a-folder"],
)
def test_bad_input_is_one_line_exit_2_nothing_written(
    config: str, tmp_path: Path, args: tuple[str, ...], expected: str
) -> None:
    if "read-only" in expected and os.geteuid() == 0:
        pytest.skip("root may write anywhere: no read-only folder to test with")
    (tmp_path / "mine.csv").write_text("precious\n")
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro").chmod(0o500)
    (tmp_path / "d.csv").mkdir()
    before = sorted(p.name for p in tmp_path.rglob("*"))
    try:
        result = run("sweep", config, *SMALL_FARM,
                     *(a.replace("{tmp}", str(tmp_path)) for a in args))
    finally:
        (tmp_path / "ro").chmod(0o700)
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1
    assert expected in result.stderr
    assert result.stdout == ""
    assert sorted(p.name for p in tmp_path.rglob("*")) == before
    assert (tmp_path / "mine.csv").read_text() == "precious\n"


def test_unreachable_scheduler_exit_2_within_10_s(config: str, tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    out = tmp_path / "r.csv"
    started = time.monotonic()
    result = run("sweep", config, *TWO_POINTS, *SMALL_FARM, "--scheduler", "tcp://127.0.0.1:9",
                 "-o", str(out))
    # Not a timing test of our code: the 10 s bound is the contract for a hang.
    assert time.monotonic() - started < 10
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith("error: --scheduler tcp://127.0.0.1:9: cannot reach")
    assert result.stderr.count("\n") == 1
    assert list(tmp_path.iterdir()) == [Path(config)]


def test_a_boolean_property_resumes_from_csv(config: str, tmp_path: Path) -> None:
    """A P>0.5 [...] property's value is written True: reading it back evaluated
    float('True') and a rerun died with a ValueError traceback."""
    out = tmp_path / "r.csv"
    args = ("sweep", config, *TWO_POINTS, *SMALL_FARM, "-j", "1", "-o", str(out),
            "--set", 'properties.b=P>0.5 [ F "success" ]', "--format", "csv")
    assert run(*args).exit_code == 0
    header, first, _ = out.read_text().splitlines()
    out.write_text(f"{header}\n{first}\n")  # interrupted after the first point
    again = run(*args)
    assert again.exit_code == 0, again.output
    assert "1 of 2 points already done" in again.stderr
    assert [row["value"] for row in csv.DictReader(again.stdout.splitlines())] == ["true"] * 2


@pytest.mark.parametrize("case", [str.lower, str.title], ids=["true-false", "older-True-False"])
def test_holds_is_written_true_false_and_older_results_still_resume(
        config: str, tmp_path: Path, case: Callable[[str], str]) -> None:
    """The results CSV said True/False where the JSON (and prism --format csv) says
    true/false; a file written so before still resumes."""
    out = tmp_path / "r.csv"
    args = ("sweep", config, *TWO_POINTS, *SMALL_FARM, "-j", "1", "-o", str(out),
            "--set", 'requirements=["exp_recharges < 9.5"]')
    assert run(*args).exit_code == 1  # fails at 10 Ah, holds at 10.5 Ah
    header, *rows = out.read_text().splitlines()
    judged = [row["holds"] for row in csv.DictReader([header, *rows]) if row["holds"]]
    assert judged == ["false", "true"]
    older = [re.sub(r",(true|false),", lambda m: f",{case(m[1])},", row) for row in rows]
    out.write_text("\n".join([header, *older[:PER_POINT]]) + "\n")  # cut after point 0
    again = run(*args, "--format", "csv")
    assert again.exit_code == 1, again.output
    assert "1 of 2 points already done" in again.stderr
    assert [row["holds"] for row in csv.DictReader(again.stdout.splitlines())
            if row["holds"]] == ["false", "true"]
    assert [row["holds"] for row in csv.DictReader(out.read_text().splitlines())
            if row["holds"]] == ["false", "true"]  # rewritten in grid order, as now
    as_json = run(*args, "--format", "json")
    assert [row["holds"] for row in json.loads(as_json.stdout)["results"]
            if row["holds"] is not None] == [False, True]


@pytest.mark.parametrize(("suffix", "edit", "line", "why"), [
    (".csv", lambda text: text.replace("\n0,", "\nx,", 1), 2,
     "invalid literal for int() with base 10: 'x'"),
    (".csv", lambda text: text.replace(",10,", ",10,nan1,", 1), 2,
     "12 cells, the header has 11"),
    (".csv", lambda text: text.rstrip("\n").rsplit(",", 3)[0] + "\n", 11,
     "8 cells, the header has 11"),
    (".csv", lambda text: text + "\xff\n", 12, "not UTF-8 text"),
    (".jsonl", lambda text: text + "{not json\n", 11, "not JSON"),
    (".jsonl", lambda text: text + "[1, 2]\n", 11, "not an object with this sweep's columns"),
    (".csv", lambda text: text.replace(",p_success,", ",bogus,", 1), 2,
     "point 0 has no property 'bogus'"),
    (".csv", lambda text: text.replace("\n1,10.5,", "\n7,10.5,", 1), 7,
     "point 7 is not one of this sweep's 2"),
    (".jsonl", lambda text: re.sub(r'"value": [^,]+', '"value": "abc"', text, count=1), 1,
     'value "abc" is not a value this sweep writes there'),
], ids=["point", "extra-cell", "missing-cells", "not-utf8", "not-json", "json-list",
        "foreign-property", "foreign-point", "json-text-value"])
def test_a_damaged_results_file_is_refused_on_one_line(
        config: str, tmp_path: Path, suffix: str, edit: object, line: int, why: str) -> None:
    """Rows the sweep did not write (edited by hand, a stray byte) gave tracebacks on
    resume (ValueError, UnicodeDecodeError); now one line naming the file's line."""
    out = tmp_path / f"r{suffix}"
    args = ("sweep", config, *TWO_POINTS, *SMALL_FARM, "-j", "1", "-o", str(out))
    assert run(*args).exit_code == 0
    damaged = edit(out.read_text())  # type: ignore[operator]
    out.write_bytes(damaged.encode().replace("\xff".encode(), b"\xff"))  # a raw 0xff byte
    before = out.read_bytes()
    again = run(*args)
    assert again.exit_code == 2, again.output
    assert again.stderr.startswith(f"error: -o {out}: line {line} is not a row this sweep "
                                   f"wrote ({why}"), again.stderr
    assert again.stderr.endswith("; use --force to start afresh, or pick another -o\n")
    assert again.stderr.count("\n") == 1 and out.read_bytes() == before


def test_a_rerun_resumes_and_redraws_the_plot_it_drew(config: str, tmp_path: Path) -> None:
    """The same command run again (the README's resumable example with --plot) resumes
    and draws its figure again; it was refused because the figure existed, and --force
    would have thrown the finished points away. A figure it did not draw stays safe."""
    out, figure = tmp_path / "r.csv", tmp_path / "p.png"
    args = ("sweep", config, *TWO_POINTS, *SMALL_FARM, "-j", "1", "-o", str(out))
    assert run(*args, "--plot", str(figure)).exit_code == 0
    again = run(*args, "--plot", str(figure))
    assert again.exit_code == 0, again.output
    assert "2 of 2 points already done" in again.stderr
    assert f"wrote {figure}" in again.stderr and figure.read_bytes().startswith(b"\x89PNG")
    # Not a figure this sweep drew (a file of the user's; another sweep's figure): refused
    # as before, and left as it is.
    mine, other = tmp_path / "mine.png", tmp_path / "other.csv"
    mine.write_bytes(b"mine")
    for results, plot in ((out, mine), (other, figure)):
        refused = run(*args[:-1], str(results), "--plot", str(plot))
        assert refused.exit_code == 2, refused.output
        assert refused.stderr == (f"error: --plot {plot}: already exists; use --force to "
                                  "overwrite it, or choose another name\n")
    assert mine.read_bytes() == b"mine" and not other.exists()


def test_a_moved_folder_resumes_and_redraws_its_plot(config: str, tmp_path: Path) -> None:
    """The figure was noted by its absolute path in RESULTS.sweep.json, so a folder of
    results and figure moved elsewhere refused to redraw it without --force (which
    would have thrown the finished points away); it is noted relative to the record."""
    first, moved = tmp_path / "first", tmp_path / "moved"
    first.mkdir()
    args = ("sweep", config, *TWO_POINTS, *SMALL_FARM, "-j", "1")
    drawn = run(*args, "-o", str(first / "r.csv"), "--plot", str(first / "p.png"))
    assert drawn.exit_code == 0, drawn.output
    noted = json.loads((first / "r.csv.sweep.json").read_text())["plots"]
    assert [entry["path"] for entry in noted] == ["p.png"]
    first.rename(moved)
    again = run(*args, "-o", str(moved / "r.csv"), "--plot", str(moved / "p.png"))
    assert again.exit_code == 0, again.output
    assert "2 of 2 points already done" in again.stderr
    assert f"wrote {moved / 'p.png'}" in again.stderr
    assert (moved / "p.png").read_bytes().startswith(b"\x89PNG")


def test_the_note_gives_the_workers_really_started(config: str) -> None:
    result = run("sweep", config, *TWO_POINTS, *SMALL_FARM, "-j", "100000")
    assert result.exit_code == 0, result.output
    assert result.stderr.splitlines()[0] == ("full build at every point; running on 2 local "
                                             "worker processes")


def test_a_bad_sweep_vary_item_is_placed_in_the_config(tmp_path: Path) -> None:
    """It was blamed on a --vary option the user never gave."""
    path = tmp_path / "mission.yaml"
    path.write_text("sweep:\n  vary:\n    - battery.capacity_ah=10,11\n"
                    "    - strategy.safe_t=0.3:0.2:0.1\n")
    result = run("sweep", str(path), *SMALL_FARM)
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr == (f"error: {path}:4:7: sweep.vary[1] 'strategy.safe_t=0.3:0.2:0.1': "
                             "STOP must be ≥ START, got 0.3:0.2\n")
    result = run("sweep", str(path), *SMALL_FARM, "--set", "sweep.vary=['farm.colz=3,4']")
    assert result.exit_code == 2
    assert result.stderr.startswith("error: --set sweep.vary[0] 'farm.colz=3,4': unknown key")


def test_the_summary_names_the_failing_requirements(config: str) -> None:
    one = ("--set", "requirements=['exp_mission_time <= 1050']")
    result = run("sweep", config, *TWO_POINTS, *SMALL_FARM, "-j", "1", *one)
    assert result.exit_code == 1
    assert result.stderr.splitlines()[-1] == ("2 points: 2 checked, 0 failed; requirement "
                                              "exp_mission_time <= 1050 fails at 1 point")
    two = ("--set", "requirements=['exp_mission_time <= 1050', 'exp_recharges <= 9']")
    result = run("sweep", config, *TWO_POINTS, *SMALL_FARM, "-j", "1", *two)
    assert result.stderr.splitlines()[-1] == (
        "2 points: 2 checked, 0 failed; requirements fail: exp_mission_time <= 1050 at 1 "
        "point, exp_recharges <= 9 at 2 points")
