"""`veribattery reproduce table3`: the paper's figures beside ours, for the right cases."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.analyses import table3
from veribattery.analyses.paper import TABLE3
from veribattery.analyses.table3 import Table3Comparison, case_overrides, reproduce_table3
from veribattery.cli import cli
from veribattery.config import load_config

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("row", TABLE3, ids=lambda r: r.case)
def test_case_files_are_the_cases_reproduce_runs(row: object) -> None:
    assert load_config(REPO / row.config) == load_config("", case_overrides(row))  # type: ignore[attr-defined]


@pytest.fixture(scope="module")
def comparisons() -> list[Table3Comparison]:
    """The four cases, checked once for the whole module (each takes seconds)."""
    return reproduce_table3()


@pytest.fixture
def cached(monkeypatch: pytest.MonkeyPatch, comparisons: list[Table3Comparison]) -> None:
    """Let the CLI reuse the module's results instead of re-checking the four cases."""
    monkeypatch.setattr(table3, "reproduce_table3", lambda progress=None: comparisons)


def test_reproduce_table3_json(cached: None) -> None:
    result = CliRunner().invoke(cli, ["reproduce", "table3", "--format", "json"])
    assert result.exit_code == 0, result.output
    rows = json.loads(result.stdout)
    assert [r["case"] for r in rows] == ["#1", "#2", "#3", "#4"]
    for row, paper in zip(rows, TABLE3, strict=True):
        assert row["paper"]["exp_recharges"] == paper.exp_recharges
        ours, theirs = row["ours"]["exp_mission_time"], paper.exp_mission_time
        assert row["relative_difference"]["exp_mission_time"] == pytest.approx(
            (ours - theirs) / theirs, rel=1e-12
        )
    # The spec's calibration (model-spec.md, last section): ≈42.7 and ≈72.4 recharges.
    assert rows[0]["ours"]["exp_recharges"] == pytest.approx(42.7713, abs=1e-4)
    assert rows[2]["ours"]["exp_recharges"] == pytest.approx(72.4300, abs=1e-4)
    assert rows[0]["states"] == rows[2]["states"] == 176_481


def test_reproduce_table3_table_names_the_source(cached: None) -> None:
    result = CliRunner().invoke(cli, ["reproduce", "table3"])
    assert result.exit_code == 0, result.output
    assert "SEFM 2019" in result.stdout
    assert "exp_recharges" in result.stdout
