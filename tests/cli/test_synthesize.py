"""``veribattery synthesize`` through CliRunner: its JSON document, CSV rows, the files
it writes, and the exit status of a requirement no strategy meets."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.cli.inputs import CASE1, SYNTHESIS
from veribattery.cli import cli
from veribattery.config import load_config
from veribattery.synthesis.bs1_values import bs1_values
from veribattery.synthesis.table_files import CSV_COLUMNS

#: The farm of SYNTHESIS as --set arguments to load_config.
SETS = [SYNTHESIS[i + 1] for i in range(0, len(SYNTHESIS), 2)]


@pytest.fixture(scope="module")
def document() -> dict[str, object]:
    result = CliRunner().invoke(cli, ["synthesize", CASE1, *SYNTHESIS, "--require", "0.9",
                                      "--format", "json"])
    assert result.exit_code == 0, result.output
    return dict(json.loads(result.stdout))


def test_json_has_the_issues_keys(document: dict[str, object]) -> None:
    assert document["model"] == {"states": 1431, "choices": 2190, "transitions": 4208}
    results = document["results"]
    assert isinstance(results, dict)
    bounds = document["bounds"]
    assert isinstance(bounds, dict)
    lower, upper = bounds["p_success_max"]
    assert lower <= results["p_success_max"] <= upper
    (fastest,) = document["fastest"]  # type: ignore[misc]
    assert fastest["requirement"] == "p_success >= 0.9" and fastest["p"] == 0.9
    assert fastest["exp_mission_time"] < fastest["exp_recharges"] * 1000
    assert set(document["strategy"]) >= {"p_success", "exp_mission_time", "rows"}  # type: ignore[arg-type]


def test_bs1_in_the_json_is_check_missions(document: dict[str, object]) -> None:
    bs1 = bs1_values(load_config(CASE1, SETS))
    assert document["bs1"] == {"safe_t": "0.3", "p_success": bs1.p_success.value,
                               "exp_mission_time": bs1.exp_mission_time.value,
                               "exp_recharges": bs1.exp_recharges.value, "states": bs1.states}


def test_files_and_csv(tmp_path: Path) -> None:
    table, figure = tmp_path / "table.csv", tmp_path / "front.png"
    result = CliRunner().invoke(cli, ["synthesize", CASE1, *SYNTHESIS, "--format", "csv",
                                      "--csv", str(table), "--pareto", str(figure)])
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(result.stdout.splitlines()))
    assert rows[0] == ["quantity", "requirement", "value", "lower", "upper"]
    assert [r[0] for r in rows[1:]][:2] == ["p_success_max", "bs1_p_success"]
    with table.open() as handle:
        assert tuple(next(csv.reader(handle))) == CSV_COLUMNS
    assert figure.read_bytes().startswith(b"\x89PNG")
    front = list(csv.DictReader((tmp_path / "front.csv").read_text().splitlines()))
    assert {r["series"] for r in front} == {"front", "bs1"}


def test_a_requirement_no_strategy_meets_exits_1() -> None:
    result = CliRunner().invoke(cli, ["synthesize", CASE1, *SYNTHESIS, "--require", "0.99"])
    assert result.exit_code == 1, result.output
    assert "FAIL p_success >= 0.99: no strategy meets it; the best P(success) is 0.9384" \
        in result.stdout


def test_the_configs_requirements_are_answered() -> None:
    required = '["p_success >= 0.9", "exp_mission_time < 5000"]'
    result = CliRunner().invoke(cli, ["synthesize", CASE1, *SYNTHESIS, "--set",
                                      f"requirements={required}", "--format", "json"])
    assert result.exit_code == 0, result.output
    (answer,) = json.loads(result.stdout)["fastest"]
    assert answer["requirement"] == "p_success >= 0.9"
    assert answer["exp_mission_time"] == pytest.approx(628.545, rel=1e-5)
    assert "requirement 'exp_mission_time < 5000' asks the MDP nothing" in result.stderr
