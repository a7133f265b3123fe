"""Durable RESULTS files: rows as points finish, resume, fingerprints, failed points."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from tests.sweep.helpers import PER_POINT, SMALL_FARM, four_axes, same_results
from veribattery.errors import ConfigError
from veribattery.sweep import Axis, run_sweep
from veribattery.sweep.fingerprint import SweepFingerprint
from veribattery.sweep.run import FIXED_COLUMNS
from veribattery.sweep.store import _reopen, csv_text, read_results


def _read(path: Path) -> pd.DataFrame:
    if path.suffix == ".parquet":
        return pd.read_parquet(path)
    if path.suffix == ".jsonl":
        return pd.DataFrame([json.loads(line) for line in path.read_text().splitlines()])
    return pd.read_csv(path)


@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".parquet"])
def test_results_file_holds_the_sweep(
    serial_frame: pd.DataFrame, tmp_path: Path, suffix: str
) -> None:
    if suffix == ".parquet":
        pytest.importorskip("pyarrow")
    path = tmp_path / f"r{suffix}"
    frame = run_sweep("", four_axes(), SMALL_FARM, results=path)
    same_results(frame, serial_frame)
    written = _read(path)
    assert list(written.columns) == list(frame.columns)
    assert list(written["point"]) == list(frame["point"])  # grid order
    assert list(written["value"].astype(float)) == list(frame["value"].astype(float))
    assert written["error"].isna().all()
    assert not (tmp_path / f"r{suffix}.partial.jsonl").exists()
    mark = SweepFingerprint.from_json((tmp_path / f"r{suffix}.sweep.json").read_text())
    assert mark.sets == SMALL_FARM


def test_rerun_resumes_and_checks_only_missing_points(
    serial_frame: pd.DataFrame, tmp_path: Path
) -> None:
    path = tmp_path / "r.csv"
    run_sweep("", four_axes(), SMALL_FARM, results=path)
    lines = path.read_text().splitlines(keepends=True)
    # Keep the header and the first point (a row per property); tear the next row in
    # half, as a crash in the middle of a write would.
    first = 1 + PER_POINT
    path.write_text("".join(lines[:first]) + lines[first][:10])
    notes: list[str] = []
    checked: list[int] = []
    frame = run_sweep("", four_axes(), SMALL_FARM, results=path, notes=notes.append,
                      on_point=lambda result, _: checked.append(result.index))
    assert notes[0] == "1 of 4 points already done"
    assert checked == [1, 2, 3]
    same_results(frame, serial_frame)
    assert list(_read(path)["point"]) == [p for p in range(4) for _ in range(PER_POINT)]
    # A third run finds everything done and checks nothing.
    notes.clear()
    again = run_sweep("", four_axes(), SMALL_FARM, results=path, notes=notes.append,
                      on_point=lambda *_: pytest.fail("checked a point again"))
    assert notes == ["4 of 4 points already done"]
    same_results(again, serial_frame)


@pytest.mark.parametrize("damage", ["row-deleted", "cut-mid-row"])
def test_a_point_with_rows_missing_is_checked_again(
    serial_frame: pd.DataFrame, tmp_path: Path, damage: str
) -> None:
    """A point counts as done only with a row for each of its properties: one whose rows
    were cut short (a results file cut mid-row: a full disk, a copy) or deleted was
    taken as done, and its missing rows never came back."""
    path = tmp_path / "r.csv"
    run_sweep("", four_axes(), SMALL_FARM, results=path)
    lines = path.read_text().splitlines(keepends=True)
    second = 1 + PER_POINT  # point 1's first row
    if damage == "row-deleted":  # point 1's third row: every point still has a row
        kept = [*lines[:second + 2], *lines[second + 3:]]
    else:  # cut in point 1's third row: points 2 and 3 lost, point 1 incomplete
        kept = [*lines[:second + 2], lines[second + 2][:15]]
    path.write_text("".join(kept))
    notes: list[str] = []
    checked: list[int] = []
    frame = run_sweep("", four_axes(), SMALL_FARM, results=path, notes=notes.append,
                      on_point=lambda result, _: checked.append(result.index))
    done = 3 if damage == "row-deleted" else 1
    assert notes[0] == (f"{done} of 4 points already done; 1 point with rows missing from "
                        "the results is checked again")
    assert checked == ([1] if damage == "row-deleted" else [1, 2, 3])
    same_results(frame, serial_frame)
    written = _read(path)
    assert list(written["point"]) == [p for p in range(4) for _ in range(PER_POINT)]
    assert list(written["value"]) == list(serial_frame["value"].astype(float))


def test_an_upper_case_suffix_is_the_same_format(tmp_path: Path) -> None:
    """``-o R.CSV`` was appended to as JSON lines and rewritten as CSV at the end (a CSV
    header over JSON rows), which no rerun could read back."""
    path = tmp_path / "R.CSV"
    axes = four_axes()[1:]
    first = run_sweep("", axes, SMALL_FARM, results=path)
    assert list(pd.read_csv(path)["point"]) == list(first["point"])
    notes: list[str] = []
    run_sweep("", axes, SMALL_FARM, results=path, notes=notes.append)
    assert notes == ["2 of 2 points already done"]


def test_torn_last_line_is_cut_before_appending(tmp_path: Path) -> None:
    path = tmp_path / "r.csv"
    path.write_text("a,b\n1,2\n3,")
    _reopen(path, ["a", "b"]).close()
    assert path.read_text() == "a,b\n1,2\n"


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"overrides": (*SMALL_FARM, "strategy.safe_t=0.25")}, "--set differs"),
        ({"axes": four_axes()[:1]}, "the axes differ"),
        ({"config": "strategy:\n  safe_t: 0.25\n"}, "the resolved base config differs"),
    ],
    ids=["set", "axes", "config"],
)
def test_results_of_another_sweep_are_refused(
    tmp_path: Path, change: dict[str, object], expected: str
) -> None:
    path = tmp_path / "r.csv"
    run_sweep("", four_axes(), SMALL_FARM, results=path)
    before = path.read_bytes()
    kwargs: dict[str, object] = {"config": "", "axes": four_axes(), "overrides": SMALL_FARM}
    kwargs |= change
    with pytest.raises(ConfigError, match=f"another sweep's results: {expected}"):
        run_sweep(results=path, **kwargs)  # type: ignore[arg-type]
    assert path.read_bytes() == before
    # --force starts afresh.
    frame = run_sweep(results=path, force=True, **kwargs)  # type: ignore[arg-type]
    assert list(_read(path)["point"]) == list(frame["point"])


def test_model_version_change_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "r.csv"
    axes = four_axes()[:1]
    run_sweep("", axes, SMALL_FARM, results=path)
    meta = tmp_path / "r.csv.sweep.json"
    data = json.loads(meta.read_text())
    meta.write_text(json.dumps({**data, "model": "veribattery 0.0.1, templates 000"}))
    with pytest.raises(ConfigError, match="the model version differs"):
        run_sweep("", axes, SMALL_FARM, results=path)


def test_a_file_that_is_not_sweep_results_is_never_overwritten(tmp_path: Path) -> None:
    path = tmp_path / "mine.csv"
    path.write_text("precious\n")
    with pytest.raises(ConfigError, match="not the results of a veribattery sweep"):
        run_sweep("", four_axes()[:1], SMALL_FARM, results=path)
    assert path.read_text() == "precious\n"


@pytest.mark.parametrize(
    ("name", "expected"),
    [("r.txt", "unsupported results type"), ("missing/r.csv", "does not exist")],
)
def test_bad_targets(tmp_path: Path, name: str, expected: str) -> None:
    with pytest.raises(ConfigError, match=expected):
        run_sweep("", four_axes(), SMALL_FARM, results=tmp_path / name,
                  on_point=lambda *_: pytest.fail("checked a point"))
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_failed_point_is_recorded_and_the_sweep_goes_on(tmp_path: Path) -> None:
    # A property that resolves but cannot be evaluated fails at the second point only (one
    # naming an undeclared label is bad input: refused before any point is checked).
    axis = Axis("properties.extra", ('P=? [ F "success" ]', "P=? [ F pow(b,-1)=0 ]"))
    path = tmp_path / "r.jsonl"
    frame = run_sweep("", [axis], SMALL_FARM, results=path)
    assert frame.attrs["failed"] == 1
    failed = frame[frame["point"] == 1]
    assert len(failed) == 1 and failed["property"].isna().all()
    assert "negative exponent" in str(failed["error"].iloc[0])
    # Setting properties.extra replaces the default properties: one property per point.
    good = frame[frame["point"] == 0].set_index("property")["value"]
    assert good["extra"] == pytest.approx(0.9999999998513445, rel=1e-9)  # as `check` gives
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    assert [r["point"] for r in rows] == [0, 1]
    assert rows[-1]["error"] == failed["error"].iloc[0]
    # A rerun retries the failed point (it fails again, recorded once).
    notes: list[str] = []
    run_sweep("", [axis], SMALL_FARM, results=path, notes=notes.append)
    assert notes[0] == "1 of 2 points already done; 1 failed point is retried"
    assert [json.loads(line)["point"] for line in path.read_text().splitlines()] == [0, 1]


@pytest.mark.parametrize(("holds", "value"), [("true", "false"), ("True", "False")],
                         ids=["true-false", "older-True-False"])
def test_read_results_takes_booleans_in_either_case(tmp_path: Path, holds: str,
                                                    value: str) -> None:
    """CSV results say true/false (as JSON does); files written True/False before still
    read back, for a resumed sweep and for report --sweep."""
    columns = ["point", "k", *FIXED_COLUMNS]
    path = tmp_path / "r.csv"
    path.write_text(",".join(columns) + f"\n0,1,b,{value},7,9,0.5,b,{holds},0.0,\n")
    [row] = read_results(path, columns)
    assert row["value"] is False and row["holds"] is True
    assert csv_text(columns, [row]).splitlines()[1] == "0,1,b,false,7,9,0.5,b,true,0.0,"
