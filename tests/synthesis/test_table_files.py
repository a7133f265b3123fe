"""The threshold table's CSV and JSON: every row and field, missing charges empty/null,
written whole (no temporary left behind, an old file replaced)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from tests.render.spec_mdp import State
from veribattery.config import derive_parameters, load_config
from veribattery.synthesis.strategy import strategy_frame
from veribattery.synthesis.table_files import (
    CSV_COLUMNS,
    threshold_json,
    write_threshold_csv,
    write_threshold_json,
)
from veribattery.synthesis.thresholds import ThresholdTable, threshold_table

SMALL = ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=6",
         "battery.max_recharges=8", "environment.p_wsp_c=0.3")


def _table() -> ThresholdTable:
    """Inspecting cell k=1 ([1,0]): a threshold at medium voltage (back at 20, on at 30),
    not one at high (on at 50, back at 55)."""
    states = [State(2, 1, 0, b, 0, 0) for b in (20, 30, 50, 55)]
    columns = {name: [getattr(x, name) for x in states] for name in State._fields}
    strategy = strategy_frame(columns, ["back", "inspect", "inspect", "back"])
    return threshold_table(strategy, derive_parameters(load_config("", SMALL)))


def test_csv(tmp_path: Path) -> None:
    path = tmp_path / "thresholds.csv"
    path.write_text("old")
    write_threshold_csv(path, _table())
    with path.open(newline="", encoding="utf-8") as stream:
        header, *rows = list(csv.reader(stream))
    assert tuple(header) == CSV_COLUMNS
    assert header[:4] == ["decision", "k", "x", "y"]
    medium, high = (dict(zip(header, row, strict=True)) for row in rows)
    assert (medium["level"], medium["least_go_on"], medium["greatest_turn_back"],
            medium["threshold"], medium["bs1_least_go_on"]) == ("medium", "30", "20", "true", "")
    assert (high["level"], high["least_go_on"], high["greatest_turn_back"], high["threshold"],
            high["threshold_across_levels"], high["bs1_least_go_on"]) == (
        "high", "50", "55", "false", "false", "54")
    assert (high["x"], high["y"], high["wind"], high["recharges"]) == ("1", "0", "low", "0")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thresholds.csv"]


def test_json(tmp_path: Path) -> None:
    path = tmp_path / "thresholds.json"
    table = _table()
    write_threshold_json(path, table)
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data == json.loads(json.dumps(threshold_json(table)))
    assert (data["charge_unit_ah"], data["non_thresholds"], len(data["rows"])) == ("0.1", 1, 2)
    medium = data["rows"][0]
    assert medium["cell"] == [1, 0]
    assert medium["bs1_least_go_on"] is None
    assert medium["threshold"] is True
    assert set(medium) == {c for c in CSV_COLUMNS if c not in ("x", "y")} | {"cell"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thresholds.json"]
