"""A sweep's results in the report: read in every format, matched to the config, turns found."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from tests.report.conftest import EXAMPLE, SECTIONS, TINY, TINY_ARGS, outline, report
from veribattery.config import load_config
from veribattery.errors import OptionError
from veribattery.report import read_sweep
from veribattery.sweep import parse_axis, run_sweep

#: P(success) of the tiny farm at 5 Ah is 0, from 6 Ah on about 0.9 (advanced) and up:
#: "p_success >= 0.85" starts to hold between 5.5 and 6 Ah.
AXES = ("battery.capacity_ah=5:6.5:0.5", "battery.model=advanced,basic_high")


def _sweep(path: Path, sets: tuple[str, ...] = TINY) -> Path:
    run_sweep(EXAMPLE, [parse_axis(a) for a in AXES], sets, results=path)
    return path


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _sweep(tmp_path_factory.mktemp("sweep") / "tiny.csv")


@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".parquet"])
def test_every_results_format_reads_alike(tmp_path: Path, results: Path, suffix: str) -> None:
    cfg = load_config(EXAMPLE, TINY)
    path = results if suffix == ".csv" else _sweep(tmp_path / f"tiny{suffix}")
    sweep = read_sweep(path, EXAMPLE, cfg)
    assert sweep.axes == ("battery.capacity_ah", "battery.model")
    assert sweep.x == "battery.capacity_ah" and sweep.points == 8 and sweep.failed == 0
    assert sweep.properties[0] == "p_success"
    holds = sweep.frame.loc[sweep.frame["property"] == "p_success", "holds"].tolist()
    assert set(holds) == {True, False}
    values = sweep.frame.loc[sweep.frame["property"] == "p_success", "value"].tolist()
    assert all(isinstance(v, float) for v in values)


def test_where_the_requirement_turns(results: Path) -> None:
    cfg = load_config(EXAMPLE, (*TINY, "battery.capacity_ah=6"))
    sweep = read_sweep(results, EXAMPLE, cfg)
    turns = {(t.line, t.before, t.after, t.stops) for t in sweep.crossings}
    assert ("battery.model=advanced", 5.5, 6.0, False) in turns
    assert all(t.requirement == "p_success >= 0.85" for t in sweep.crossings)
    assert sweep.here == 6.0 and sweep.note == ""


def test_the_report_draws_the_sweep(tmp_path: Path, results: Path) -> None:
    target = tmp_path / "with-sweep.html"
    result = report(EXAMPLE, *TINY_ARGS, "--set", "battery.capacity_ah=6", "--sweep",
                    str(results), "-o", str(target), "--runs", "100")
    assert result.exit_code == 0, result.output
    page = target.read_text(encoding="utf-8")
    found = outline(page)
    assert all(section in found.ids for section in SECTIONS)
    sweep_figures = [svg for svg in found.svgs if str(svg["id"]).startswith("fig-sweep-")]
    assert len(sweep_figures) == 5  # one per property of the results
    assert 'id="crossings"' in page and "holds again" in page
    assert "this report" in page


def _refused(tmp_path: Path, results: Path, *sets: str) -> str:
    target = tmp_path / "refused.html"
    result = report(EXAMPLE, *TINY_ARGS, *sets, "--sweep", str(results), "-o", str(target))
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith("error: --sweep ") and result.stderr.count("\n") == 1
    assert not target.exists()
    return result.stderr


def test_a_sweep_of_other_fixed_keys_is_refused(tmp_path: Path, results: Path) -> None:
    message = _refused(tmp_path, results, "--set", "environment.p_wsp_c=0.2")
    assert "a sweep of another config: environment.p_wsp_c is 0.1 there, 0.2 here" in message
    assert "(only the varied keys battery.capacity_ah, battery.model may differ)" in message


def test_a_sweep_of_another_config_file_is_refused(tmp_path: Path, results: Path) -> None:
    other = tmp_path / "other.yaml"
    other.write_text("times_min: {recharge: 60}\n")
    target = tmp_path / "refused.html"
    result = report(str(other), *TINY_ARGS, "--sweep", str(results), "-o", str(target))
    assert result.exit_code == 2 and not target.exists()
    assert "a sweep of another config: its base config differs" in result.stderr


def test_varying_a_varied_key_is_not_a_difference(results: Path) -> None:
    cfg = load_config(EXAMPLE, (*TINY, "battery.capacity_ah=12.8", "battery.model=basic_low"))
    assert read_sweep(results, EXAMPLE, cfg).here == 12.8


def test_results_without_their_fingerprint_are_refused(tmp_path: Path, results: Path) -> None:
    copy = tmp_path / "copy.csv"
    copy.write_bytes(results.read_bytes())
    assert "no copy.csv.sweep.json beside it" in _refused(tmp_path, copy)
    copy.with_name("copy.csv.sweep.json").write_text('{"something": "else"}')
    assert "is not a veribattery sweep fingerprint" in _refused(tmp_path, copy)


def test_a_file_that_is_not_results_is_refused(tmp_path: Path, results: Path) -> None:
    wrong = tmp_path / "wrong.csv"
    wrong.write_text("a,b\n1,2\n")
    meta = results.with_name(results.name + ".sweep.json").read_text()
    wrong.with_name("wrong.csv.sweep.json").write_text(meta)
    assert "its columns are not those of the sweep" in _refused(tmp_path, wrong)
    text = tmp_path / "results.txt"
    text.write_text("")
    assert "not a sweep's results file" in _refused(tmp_path, text)


def test_a_cell_the_sweep_did_not_write_is_refused_naming_its_line(
        tmp_path: Path, results: Path) -> None:
    """Read as ``sweep`` reads its results when it resumes: a value ``abc`` was drawn."""
    edited = tmp_path / "edited.csv"
    lines = results.read_text().splitlines(keepends=True)
    cells = lines[1].split(",")
    cells[4] = "abc"  # the first row's value (after point and the two varied keys)
    edited.write_text("".join([lines[0], ",".join(cells), *lines[2:]]))
    meta = results.with_name(results.name + ".sweep.json").read_text()
    edited.with_name("edited.csv.sweep.json").write_text(meta)
    assert _refused(tmp_path, edited) == (
        f"error: --sweep {edited}: line 2 is not a row this sweep wrote (could not convert "
        "string to float: 'abc')\n")


def test_an_unreadable_results_file_is_refused(tmp_path: Path, results: Path) -> None:
    broken = tmp_path / "broken.parquet"
    broken.write_bytes(b"not parquet")
    meta = json.loads(results.with_name(results.name + ".sweep.json").read_text())
    broken.with_name("broken.parquet.sweep.json").write_text(json.dumps(meta))
    assert "cannot read it" in _refused(tmp_path, broken)


def test_read_sweep_raises_an_option_error(tmp_path: Path) -> None:
    with pytest.raises(OptionError, match="no such file"):
        read_sweep(tmp_path / "none.csv", EXAMPLE, load_config(EXAMPLE, TINY))


def test_a_turn_is_between_neighbours_only(results: Path) -> None:
    sweep = read_sweep(results, EXAMPLE, load_config(EXAMPLE, TINY))
    for turn in sweep.crossings:
        assert turn.after - turn.before == pytest.approx(0.5)
        assert math.isfinite(turn.after_value)
