"""The threshold table as files: CSV (one row per table row) and JSON.

Both are written all or nothing through :mod:`veribattery._files`: an error leaves the
user's old file (or none) and no temporary behind. Charges are whole units of
``charge_unit_ah`` (the config's ``battery.resolution_ah``); a missing charge (no state
goes on, or none turns back) is an empty CSV field and ``null`` in JSON.
"""

from __future__ import annotations

import csv
import json
from dataclasses import fields
from pathlib import Path
from typing import Any

from veribattery._files import staged, write_text
from veribattery.synthesis.thresholds import ThresholdRow, ThresholdTable

__all__ = ["CSV_COLUMNS", "threshold_json", "write_threshold_csv", "write_threshold_json"]

#: The CSV's columns: the row's fields, the cell split into x and y.
CSV_COLUMNS = tuple(
    column for f in fields(ThresholdRow)
    for column in (("x", "y") if f.name == "cell" else (f.name,))
)


def threshold_json(table: ThresholdTable) -> dict[str, Any]:
    """The table as JSON-ready data: ``{"charge_unit_ah", "non_thresholds", "rows"}``."""
    return {"charge_unit_ah": table.charge_unit_ah,
            "non_thresholds": len(table.non_thresholds),
            "rows": [row.as_dict() for row in table.rows]}


def write_threshold_json(path: Path, table: ThresholdTable) -> None:
    """Write :func:`threshold_json` to *path* (indented, UTF-8), atomically."""
    write_text(path, json.dumps(threshold_json(table), indent=2) + "\n")


def write_threshold_csv(path: Path, table: ThresholdTable) -> None:
    """Write the table to *path* as CSV, header :data:`CSV_COLUMNS`, atomically."""
    with staged(path) as temporary, open(temporary, "w", encoding="utf-8", newline="") as out:
        writer = csv.writer(out)
        writer.writerow(CSV_COLUMNS)
        writer.writerows(_csv_row(row) for row in table.rows)


def _csv_row(row: ThresholdRow) -> list[object]:
    values = row.as_dict()
    del values["cell"]
    values |= {"x": row.cell[0], "y": row.cell[1]}
    return [_field(values[column]) for column in CSV_COLUMNS]


def _field(value: object) -> object:
    """None as an empty field; booleans as ``true``/``false``, as in the JSON."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value).lower()
    return value
