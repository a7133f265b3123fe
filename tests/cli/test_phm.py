"""The phm commands and recheck through CliRunner: outputs, files, exit codes, bad input."""

from __future__ import annotations

import csv
import io
import json
import os
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner, Result

from tests.cli.terminal import run_in_terminal
from tests.phm.helpers import EXAMPLES, cycles_csv
from veribattery.cli import cli

SMALL = ("--set", "farm.cols=3", "--set", "farm.rows=3", "--set", "farm.base=[0,0]")
PNG = b"\x89PNG\r\n\x1a\n"
MISSION = "# my mission\nbattery:\n  capacity_ah: 11  # as bought\n  max_recharges: 50\n" \
          "requirements: ['p_success >= 0.99']  # CI gate\n"


def run(*args: str) -> Result:
    return CliRunner().invoke(cli, list(args))


def _fading(tmp_path: Path) -> Path:
    cycles = np.arange(0, 101, 10.0)
    return cycles_csv(tmp_path / "cycles.csv", cycles, 6.0 - 0.03 * cycles)


def test_fade_prints_fits_choice_and_fragment(tmp_path: Path) -> None:
    png = tmp_path / "fade.png"
    result = run("phm", "fade", str(EXAMPLES / "cycles.csv"), "--plot", str(png))
    assert result.exit_code == 0, result.output
    for text in ("linear", "exponential", "knee", "choice:", "lowest AIC", "95% CI",
                 "residuals", "capacity_ah: 9.5\n", "fade_per_recharge: 0.000145"):
        assert text in result.output
    assert png.read_bytes().startswith(PNG)


def test_fade_write_keeps_comments(tmp_path: Path) -> None:
    config = tmp_path / "m.yaml"
    config.write_text(MISSION)
    result = run("phm", "fade", str(_fading(tmp_path)), "--write", str(config), "--at-cycle", "50")
    assert result.exit_code == 0, result.output
    text = config.read_text()
    assert text == MISSION.replace("capacity_ah: 11  # as bought",
                                   "capacity_ah: 4.5  # as bought").replace(
        "  max_recharges: 50\n", "  max_recharges: 50\n  fade_per_recharge: 0.00667\n")


def _write_args(command: str, tmp_path: Path, config: Path) -> list[str]:
    data = "cycles.csv" if command == "fade" else "discharge.csv"
    return ["phm", command, str(EXAMPLES / data), "--write", str(config)]


@pytest.mark.parametrize("command", ["fade", "levels"])
def test_write_follows_a_symbolic_link(tmp_path: Path, command: str) -> None:
    """The link was replaced by a regular file and the config it points to left as it
    was: the user's config silently not updated."""
    (tmp_path / "configs").mkdir()
    real = tmp_path / "configs" / "m.yaml"
    real.write_text(MISSION)
    link = tmp_path / "link.yaml"
    link.symlink_to(real)
    result = run(*_write_args(command, tmp_path, link))
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and link.resolve() == real
    merged = yaml.safe_load(real.read_text())["battery"]
    assert ("fade_per_recharge" if command == "fade" else "voltage_thresholds") in merged
    assert sorted(p.name for p in tmp_path.iterdir()) == ["configs", "link.yaml"]


@pytest.mark.parametrize("command", ["fade", "levels"])
def test_write_keeps_crlf_line_endings(tmp_path: Path, command: str) -> None:
    config = tmp_path / "m.yaml"
    config.write_bytes(MISSION.replace("\n", "\r\n").encode())
    result = run(*_write_args(command, tmp_path, config))
    assert result.exit_code == 0, result.output
    data = config.read_bytes()
    assert data.count(b"\n") == data.count(b"\r\n") > MISSION.count("\n")
    assert b"# as bought\r\n" in data


@pytest.mark.parametrize("command", ["fade", "levels"])
def test_write_refuses_a_hard_linked_config_before_any_work(tmp_path: Path,
                                                            command: str) -> None:
    config, other = tmp_path / "m.yaml", tmp_path / "copy.yaml"
    config.write_text(MISSION)
    os.link(config, other)
    png = tmp_path / "fit.png"
    result = run(*_write_args(command, tmp_path, config), "--plot", str(png))
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr == (f"error: --write {config}: the file has 2 hard links, and --write "
                             "replaces it by a new file, which would split them; give a file "
                             "with one name (a symbolic link to it is followed), or merge the "
                             "fragment by hand\n")
    assert config.read_text() == MISSION and os.path.samefile(config, other)
    assert not png.exists()


def test_fade_write_lists_the_file_on_stderr_and_restates_stale_comments(
        tmp_path: Path) -> None:
    """'merged ... into pm.yaml (comments kept)' was printed on stdout, unlike every other
    command's 'wrote FILE' on stderr; the comment of the old fade stayed beside the new."""
    config = tmp_path / "pm.yaml"
    example = (EXAMPLES / "mission.yaml").read_text()
    config.write_text(example)
    result = run("phm", "fade", str(EXAMPLES / "cycles.csv"), "--write", str(config))
    assert result.exit_code == 0, result.output
    assert result.stderr == f"wrote {config}\n"
    assert result.stdout.endswith("# YAML fragment for the mission config:\nbattery:\n"
                                  "  capacity_ah: 9.5\n  fade_per_recharge: 0.000145\n")
    assert config.read_text() == example.replace(
        "capacity_ah: 11 ", "capacity_ah: 9.5 ").replace(
        "fade_per_recharge: 0.002 # BA1 (0.2 % per recharge)",
        "fade_per_recharge: 0.000145 # fitted by veribattery phm fade from cycles.csv")


def test_fade_write_refuses_invalid_result_and_keeps_file(tmp_path: Path) -> None:
    config = tmp_path / "m.yaml"
    config.write_text("battery:\n  max_recharges: 200  # long missions\n")
    result = run("phm", "fade", str(_fading(tmp_path)), "--write", str(config))
    assert result.exit_code == 2
    assert "max_recharges" in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert config.read_text() == "battery:\n  max_recharges: 200  # long missions\n"


@pytest.mark.parametrize(("text", "message"), [
    ("cycle,capacity_ah\n0,11\n1,x\n2,10\n", "c.csv:3: row 2, column 'capacity_ah'"),
    ("cycle,cap\n0,11\n", "c.csv:1: header: missing column 'capacity_ah'"),
    ("cycle,capacity_ah\n0,11\n1,10\n", "at least 3 cycles"),
])
def test_fade_bad_input_one_line_exit_2(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "c.csv"
    path.write_text(text)
    result = run("phm", "fade", str(path))
    assert result.exit_code == 2
    assert message in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.output
    assert result.stdout == ""


def test_the_docs_fade_example_is_what_the_command_prints(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """docs/commands/phm.md showed a CI of [0.0001448, 0.0001453], the command printed
    [0.0001447, 0.0001453]: the 4th digit depended on where curve_fit stopped near the
    knee. The fit is now exact, and the page shows the whole output, line for line."""
    command = "veribattery phm fade examples/phm/cycles.csv --plot fade.png"
    doc = (EXAMPLES.parents[1] / "docs" / "commands" / "phm.md").read_text()
    shown = doc.split(f"$ {command}\n", 1)[1].split("```", 1)[0].splitlines()
    monkeypatch.chdir(tmp_path)
    result = run("phm", "fade", str(EXAMPLES / "cycles.csv"), "--plot", "fade.png")
    assert result.exit_code == 0, result.output
    printed = result.stdout.splitlines() + result.stderr.splitlines()
    assert shown == printed


def test_the_example_config_points_at_docs_that_exist() -> None:
    """Its first line sent readers to a README section that does not exist."""
    text = (EXAMPLES / "mission.yaml").read_text()
    named = re.findall(r"docs/[\w/.-]+\.md", text)
    assert named and all((EXAMPLES.parents[1] / name).is_file() for name in named)
    assert "README" not in text


def test_plot_never_overwrites(tmp_path: Path) -> None:
    png = tmp_path / "mine.png"
    png.write_bytes(b"keep")
    result = run("phm", "fade", str(EXAMPLES / "cycles.csv"), "--plot", str(png))
    assert result.exit_code == 2 and "already exists" in result.stderr
    assert png.read_bytes() == b"keep"


def test_levels_on_example(tmp_path: Path) -> None:
    config = tmp_path / "m.yaml"
    config.write_text(MISSION)
    png = tmp_path / "levels.png"
    result = run("phm", "levels", str(EXAMPLES / "discharge.csv"), "--write", str(config),
                 "--plot", str(png))
    assert result.exit_code == 0, result.output
    assert "thresholds: low SOC < 0.19" in result.output
    assert "RMS" in result.output and "Eq. 2 consumption" in result.output
    merged = yaml.safe_load(config.read_text())
    assert merged["battery"]["voltage_thresholds"] == {"high": 0.65, "low": 0.19}
    assert "# as bought" in config.read_text() and "# CI gate" in config.read_text()
    assert png.read_bytes().startswith(PNG)


def test_levels_bad_soc_step(tmp_path: Path) -> None:
    result = run("phm", "levels", str(EXAMPLES / "discharge.csv"), "--soc-step", "abc")
    assert result.exit_code == 2 and "--soc-step" in result.stderr


def test_recheck_exit_1_on_regression(tmp_path: Path) -> None:
    config = tmp_path / "m.yaml"
    config.write_text(MISSION)
    result = run("recheck", str(config), "--cycles", str(_fading(tmp_path)), *SMALL)
    assert result.exit_code == 1, result.output
    assert "battery.capacity_ah: 11 → 3" in result.output
    assert "p_success >= 0.99: before PASS, after FAIL" in result.output
    assert "no longer holds: p_success >= 0.99" in result.output
    assert config.read_text() == MISSION  # recheck never edits the config


def test_recheck_bad_data_exit_2(tmp_path: Path) -> None:
    config = tmp_path / "m.yaml"
    config.write_text(MISSION)
    bad = tmp_path / "d.csv"
    bad.write_text("soc,voltage_v\n1,25\n0.5,26\n0,20\n")
    result = run("recheck", str(config), "--cycles", str(_fading(tmp_path)), "--discharge",
                 str(bad), *SMALL)
    assert result.exit_code == 2
    assert "d.csv:3: row 2, column 'voltage_v'" in result.stderr


def test_forecast_cli(tmp_path: Path) -> None:
    config = tmp_path / "m.yaml"
    config.write_text(MISSION)
    png = tmp_path / "forecast.png"
    cycles = np.arange(0, 51, 5.0)
    log = cycles_csv(tmp_path / "c.csv", cycles, 8.6 - 0.032 * cycles)
    result = run("phm", "forecast", str(config), "--cycles", str(log), "--horizon", "20",
                 "--step", "10", "--plot", str(png), *SMALL)
    assert result.exit_code == 1, result.output  # the requirement fails within the horizon
    assert "stops holding after" in result.output
    assert png.read_bytes().startswith(PNG)


def _forecast_args(tmp_path: Path) -> list[str]:
    config = tmp_path / "m.yaml"
    config.write_text(MISSION)
    cycles = np.arange(0, 51, 5.0)
    log = cycles_csv(tmp_path / "c.csv", cycles, 8.6 - 0.032 * cycles)
    return ["phm", "forecast", str(config), "--cycles", str(log), "--horizon", "20", "--step",
            "10", *SMALL]


def test_forecast_tells_each_age_on_a_pipe(tmp_path: Path,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """A forecast of the paper's farm ran 10 s without a word; in a log each age is a line
    (from the first here: every report is a line with VERIBATTERY_PROGRESS_S=0,0)."""
    args = _forecast_args(tmp_path)
    quiet = run(*args)
    assert quiet.exit_code == 1 and quiet.stderr == ""  # a short run says nothing
    monkeypatch.setenv("VERIBATTERY_PROGRESS_S", "0,0")
    told = run(*args)
    assert told.exit_code == 1 and told.stdout == quiet.stdout
    assert told.stderr.splitlines() == [
        "checking the mission at cycle 50 (age 1 of 3)",
        "checking the mission at cycle 60 (age 2 of 3)",
        "checking the mission at cycle 70 (age 3 of 3)",
        "checking the mission at cycle 55 (age 4, bisecting)",
        "checking the mission at cycle 57 (age 5, bisecting)",
        "checking the mission at cycle 58 (age 6, bisecting)"]


def test_forecast_spinner_names_the_age_and_is_erased(tmp_path: Path) -> None:
    screen = run_in_terminal(_forecast_args(tmp_path), 80, tmp_path)
    assert screen.status == 1, screen.text  # it stops holding within the horizon
    assert "checking the mission at cycle " in screen.drawn
    assert "checking" not in screen.text and "stops holding after 8 more cycles" in screen.text


def test_forecast_bad_requirement(tmp_path: Path) -> None:
    result = run("phm", "forecast", str(EXAMPLES / "mission.yaml"), "--cycles",
                 str(EXAMPLES / "cycles.csv"), "--require", "p_success ~ 1")
    assert result.exit_code == 2 and "--require" in result.stderr


def test_fade_json_is_one_object_with_the_table_numbers(tmp_path: Path) -> None:
    png = tmp_path / "fade.png"
    result = run("phm", "fade", str(EXAMPLES / "cycles.csv"), "--format", "json",
                 "--plot", str(png))
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["cycles"] == str(EXAMPLES / "cycles.csv")
    assert [f["model"] for f in doc["fits"]] == ["knee", "exponential", "linear"]
    assert doc["model"] == "knee" and doc["at_cycle"] == 30
    assert doc["capacity_ah"] == 9.5 and doc["fade_per_recharge"] == 0.000145
    assert doc["capacity_fit_ah"] == pytest.approx(9.5082, abs=5e-5)
    low, high = doc["fade_ci95"]
    assert low < doc["fade_per_cycle"] < high
    assert doc["fragment"] == {"battery.capacity_ah": 9.5, "battery.fade_per_recharge": 0.000145}
    assert doc["fragment_yaml"].startswith("battery:\n  capacity_ah: 9.5\n")
    assert doc["figure"] == str(png) and doc["merged_into"] is None
    assert png.read_bytes().startswith(PNG)


def test_levels_json(tmp_path: Path) -> None:
    result = run("phm", "levels", str(EXAMPLES / "discharge.csv"), "--format", "json")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["thresholds"] == {"low": 0.19, "high": 0.65}
    assert list(doc["voltages_v"]) == ["low", "medium", "high"]
    assert doc["config_thresholds"]["low"] == 0.25
    assert doc["consumption_units"]["inspection"]["high_wind"] == {"low": 103, "medium": 90,
                                                                   "high": 81}
    assert doc["fragment"]["battery.voltage_thresholds.low"] == 0.19


def test_forecast_json_and_csv(tmp_path: Path) -> None:
    config = tmp_path / "m.yaml"
    config.write_text(MISSION)
    cycles = np.arange(0, 51, 5.0)
    log = cycles_csv(tmp_path / "c.csv", cycles, 8.6 - 0.032 * cycles)
    args = ("phm", "forecast", str(config), "--cycles", str(log), "--horizon", "20", "--step",
            "10", *SMALL)
    result = run(*args, "--format", "json")
    assert result.exit_code == 1, result.output
    doc = json.loads(result.stdout)
    assert doc["requirement"] == "p_success >= 0.99" and doc["now"] == 50
    assert doc["fails_after"] == 8 and doc["fails_at_cycle"] == 58
    assert [p["ahead"] for p in doc["points"]] == [0, 5, 7, 8, 10, 20]
    assert [p["holds"] for p in doc["points"]] == [True, True, True, False, False, False]
    assert doc["points"][0]["capacity_ah"] == 7 and "exp_mission_time" in doc["points"][0]["values"]
    rows = list(csv.reader(io.StringIO(run(*args, "--format", "csv").stdout)))
    assert rows[0] == ["ahead", "cycle", "capacity_ah", "fade_per_recharge", "p_success",
                       "exp_mission_time", "holds"]
    assert rows[1][:4] == ["0", "50", "7", "0.00457"] and rows[1][-1] == "true"
    assert float(rows[4][4]) == doc["points"][3]["values"]["p_success"]


def test_recheck_json_exit_1_on_regression(tmp_path: Path) -> None:
    config = tmp_path / "m.yaml"
    config.write_text(MISSION)
    result = run("recheck", str(config), "--cycles", str(_fading(tmp_path)), *SMALL,
                 "--format", "json")
    assert result.exit_code == 1, result.output
    doc = json.loads(result.stdout)
    assert doc["moved"][0] == {"key": "battery.capacity_ah", "before": 11, "after": 3}
    assert doc["requirements"] == [{"requirement": "p_success >= 0.99", "before": True,
                                    "after": False}]
    assert doc["regressions"] == ["p_success >= 0.99"]
    p_success = doc["properties"]["p_success"]
    assert p_success["change"] == pytest.approx(p_success["after"] - p_success["before"])
