"""``veribattery prism`` output for filters, ranges and unsupported properties."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from tests.checker.test_pctl_language import MODEL
from veribattery.cli import cli


def _run(tmp_path: Path, *args: str) -> tuple[int, str, str]:
    model = tmp_path / "m.prism"
    model.write_text(MODEL)
    result = CliRunner().invoke(cli, ["prism", str(model), *args])
    return result.exit_code, result.stdout, result.stderr


def test_json_lists_printed_states_and_ranges(tmp_path: Path) -> None:
    code, out, _ = _run(tmp_path, "--property", "filter(printall, s*2, s>2)",
                        "--property", "filter(range, s)", "--json")
    assert code == 0
    first, second = json.loads(out)["results"]
    assert first["states"] == ["3:(s=3)=6", "4:(s=4)=8"]
    assert (second["value"], second["range"]) == (0, [0, 4])


def test_table_shows_a_range_and_the_states(tmp_path: Path) -> None:
    code, out, _ = _run(tmp_path, "--property", "filter(range, s)",
                        "--property", "filter(argmax, s)")
    assert code == 0
    assert "[0, 4]" in out and "4:(s=4)" in out


def test_picked_bounded_ltl_property_is_one_line_exit_2(tmp_path: Path) -> None:
    code, out, err = _run(tmp_path, "--property", "P=? [ F<=2 G s=1 ]", "--json")
    assert code == 2 and out == ""
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "LTL takes unbounded operators only" in lines[0]


def test_whole_file_skips_bounded_ltl_with_a_warning(tmp_path: Path) -> None:
    props = tmp_path / "p.props"
    props.write_text("P=? [ F<=2 G s=1 ]\nS=? [ s=3 ]\nP=? [ G F s=1 ]\n")
    code, out, err = _run(tmp_path, "--props", str(props), "--json")
    assert code == 0
    assert [r["property"] for r in json.loads(out)["results"]] == [
        "S=? [ s=3 ]", "P=? [ G F s=1 ]"]
    assert "warning" in err and "LTL takes unbounded operators only" in err
