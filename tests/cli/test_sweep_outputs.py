"""`veribattery sweep`'s outputs beside RESULTS and its option clashes, as a user meets them.

Each case was found by a robustness pass: a fingerprint file of the user's replaced, a
figure the user had replaced redrawn, a ``--set`` silently dropped, and messages unlike
every other command's. Every refusal is one line, exit 2, and leaves every file as it was.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import Result

from tests.cli.terminal import run_in_terminal
from tests.sweep.helpers import SMALL_FARM as TINY
from tests.sweep.helpers import TWO_POINTS, run
from veribattery.cli.files import FIGURE_SUFFIXES

SMALL_FARM = tuple(arg for item in TINY for arg in ("--set", item))


def _sweep(config: str, *args: str) -> tuple[str, ...]:
    return ("sweep", config, *TWO_POINTS, *SMALL_FARM, "-j", "1", *args)


def _refused(result: Result, message: str) -> None:
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    assert result.stderr == f"error: {message}\n"


def test_a_fingerprint_file_without_its_results_is_not_overwritten(
        config: str, tmp_path: Path) -> None:
    """``-o R.csv`` replaced an existing ``R.csv.sweep.json`` when R.csv did not exist."""
    out, meta = tmp_path / "results.csv", tmp_path / "results.csv.sweep.json"
    meta.write_text('{"my":"notes"}\n')
    result = run(*_sweep(config, "-o", str(out)))
    _refused(result, f"-o {out}: {meta} already exists (and {out} does not); use --force to "
             "overwrite it, or choose another name")
    assert meta.read_bytes() == b'{"my":"notes"}\n' and not out.exists()
    forced = run(*_sweep(config, "-o", str(out), "--force"))
    assert forced.exit_code == 0, forced.output
    assert json.loads(meta.read_text())["veribattery_sweep"] == 1


def test_a_parquet_sweep_cut_short_still_resumes_beside_its_fingerprint(
        config: str, tmp_path: Path) -> None:
    """Its rows are in the journal until it ends: the fingerprint is then not alone."""
    out = tmp_path / "r.parquet"
    assert run(*_sweep(config, "-o", str(out))).exit_code == 0
    journal = tmp_path / "r.parquet.partial.jsonl"
    journal.write_text("")  # as a first run interrupted before its first point leaves it
    out.unlink()
    again = run(*_sweep(config, "-o", str(out)))
    assert again.exit_code == 0, again.output
    assert out.exists()


@pytest.mark.parametrize("force", [(), ("--force",)], ids=["plain", "force"])
def test_a_fingerprint_path_that_is_a_folder_is_named_with_o(
        config: str, tmp_path: Path, force: tuple[str, ...]) -> None:
    out, meta = tmp_path / "d.csv", tmp_path / "d.csv.sweep.json"
    meta.mkdir()
    (meta / "keep").write_text("mine")
    result = run(*_sweep(config, "-o", str(out), *force))
    _refused(result, f"-o {out}: {meta}, where the sweep keeps its fingerprint, is a folder; "
             "move it away, or choose another name")
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["d.csv.sweep.json", "keep",
                                                          "mission.yaml"]


@pytest.mark.parametrize("replace", [
    lambda figure: figure.write_bytes(b"x\n"),
    lambda figure: figure.write_bytes(figure.read_bytes() + b"edited"),
], ids=["replaced", "edited"])
def test_a_plot_changed_since_the_sweep_drew_it_is_not_redrawn(
        config: str, tmp_path: Path, replace: object) -> None:
    """A rerun that resumes redrew a --plot file the user had replaced since."""
    out, figure = tmp_path / "q.csv", tmp_path / "q.png"
    assert run(*_sweep(config, "-o", str(out), "--plot", str(figure))).exit_code == 0
    replace(figure)  # type: ignore[operator]
    theirs, results, record = (p.read_bytes() for p in
                               (figure, out, tmp_path / "q.csv.sweep.json"))
    again = run(*_sweep(config, "-o", str(out), "--plot", str(figure)))
    _refused(again, f"--plot {figure}: changed since this sweep drew it; use --force to "
             f"overwrite it (and start {out} afresh), or move it away")
    assert figure.read_bytes() == theirs and out.read_bytes() == results
    assert (tmp_path / "q.csv.sweep.json").read_bytes() == record
    forced = run(*_sweep(config, "-o", str(out), "--plot", str(figure), "--force"))
    assert forced.exit_code == 0, forced.output
    assert figure.read_bytes().startswith(b"\x89PNG")


def test_an_older_record_without_a_digest_needs_force(config: str, tmp_path: Path) -> None:
    """Records of older versions noted a figure's path only (absolute, or relative), so
    whether it changed since cannot be told: it is treated as changed."""
    out, figure = tmp_path / "r.csv", tmp_path / "p.png"
    args = _sweep(config, "-o", str(out), "--plot", str(figure))
    assert run(*args).exit_code == 0
    record = tmp_path / "r.csv.sweep.json"
    for noted in (str(figure.resolve()), "p.png"):
        record.write_text(json.dumps({**json.loads(record.read_text()), "plots": [noted]}))
        drawn = figure.read_bytes()
        again = run(*args)
        _refused(again, f"--plot {figure}: drawn by an older version, which kept no digest to "
                 f"tell it unchanged; use --force to overwrite it (and start {out} afresh), "
                 "or move it away")
        assert figure.read_bytes() == drawn


def test_a_plot_drawn_again_is_noted_once_with_its_new_digest(
        config: str, tmp_path: Path) -> None:
    out, figure = tmp_path / "r.csv", tmp_path / "p.png"
    args = _sweep(config, "-o", str(out), "--plot", str(figure))
    for _ in range(2):
        assert run(*args).exit_code == 0
    (entry,) = json.loads((tmp_path / "r.csv.sweep.json").read_text())["plots"]
    assert entry["path"] == "p.png" and len(entry["sha256"]) == 64


@pytest.mark.parametrize(("given", "varied_by"), [
    (("--vary", "battery.capacity_ah=10,10.5"), "--vary"),
    (("--set", "sweep.vary=['battery.capacity_ah=10,10.5']"), "the config's sweep.vary"),
], ids=["vary", "sweep.vary"])
def test_a_set_of_a_varied_key_is_refused(
        config: str, tmp_path: Path, given: tuple[str, ...], varied_by: str) -> None:
    """Every point's value replaced the --set, which was dropped without a word."""
    out = tmp_path / "r.csv"
    result = run("sweep", config, *given, *SMALL_FARM, "--set", "battery.capacity_ah=9",
                 "-o", str(out))
    _refused(result, f"--set battery.capacity_ah=9: battery.capacity_ah is also varied by "
             f"{varied_by}; drop one")
    assert not out.exists()


def test_a_folder_as_results_says_so(config: str, tmp_path: Path) -> None:
    for folder in (".", str(tmp_path)):
        _refused(run(*_sweep(config, "-o", folder)),
                 f"-o {folder}: is a folder; name a results file (.csv, .jsonl or .parquet) "
                 "in it")
    assert [p.name for p in tmp_path.iterdir()] == ["mission.yaml"]


@pytest.mark.parametrize("name", ["x.csv", "x.gif", "x"])
def test_plot_file_types_are_every_commands(config: str, tmp_path: Path, name: str) -> None:
    """sweep listed matplotlib's own types (.avif, .gif, .raw, .rgba, ...) and quoted the
    path, unlike every other command's --plot."""
    plot = tmp_path / name
    kind = f"unsupported file type '{plot.suffix}'" if plot.suffix else "no file type"
    _refused(run(*_sweep(config, "--plot", str(plot))),
             f"--plot {plot}: {kind}; name a file ending in "
             f"{', '.join(FIGURE_SUFFIXES[:-1])} or {FIGURE_SUFFIXES[-1]}")
    assert not plot.exists()


def test_the_refusals_read_whole_in_an_80_column_terminal(config: str, tmp_path: Path) -> None:
    (tmp_path / "r.csv.sweep.json").write_text("{}")
    screen = run_in_terminal(["sweep", config, "--vary", "battery.capacity_ah=10,11",
                              "-o", "r.csv"], 80, tmp_path)
    assert screen.status == 2
    assert " ".join(screen.text.split()) == (
        "error: -o r.csv: r.csv.sweep.json already exists (and r.csv does not); use --force "
        "to overwrite it, or choose another name")
    assert (tmp_path / "r.csv.sweep.json").read_text() == "{}"
