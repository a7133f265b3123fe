"""Synthesis: the mission as an MDP (model-spec.md, "Synthesis"), its files and questions,
and what a synthesised strategy means in the mission's words.

Modules: :mod:`~veribattery.synthesis.files` (what ``emit`` writes),
:mod:`~veribattery.synthesis.strategy` (a strategy state by state, the tables' input),
:mod:`~veribattery.synthesis.decisions` (where the drone decides to go on),
:mod:`~veribattery.synthesis.levels` (voltage levels per state),
:mod:`~veribattery.synthesis.bs1_rule` (BS1's rule as a charge threshold),
:mod:`~veribattery.synthesis.thresholds` (the threshold table) and
:mod:`~veribattery.synthesis.table_files` (its CSV and JSON),
:mod:`~veribattery.synthesis.pareto` (the Pareto front's figure and CSV) and
:mod:`~veribattery.synthesis.bs1_values` (BS1's points on it).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from veribattery.synthesis.files import synthesis_files, unasked_requirements

if TYPE_CHECKING:
    from veribattery.synthesis.bs1_rule import bs1_least_go_on
    from veribattery.synthesis.bs1_values import bs1_points
    from veribattery.synthesis.pareto import (
        Bs1Point,
        FrontPoint,
        pareto_figure,
        write_pareto_csv,
        write_pareto_figure,
    )
    from veribattery.synthesis.strategy import StrategyError, strategy_frame
    from veribattery.synthesis.table_files import (
        threshold_json,
        write_threshold_csv,
        write_threshold_json,
    )
    from veribattery.synthesis.thresholds import ThresholdRow, ThresholdTable, threshold_table

# Imported on first use: pandas and matplotlib are not needed to emit a model.
_EXPORTS = {
    "veribattery.synthesis.bs1_rule": ("bs1_least_go_on",),
    "veribattery.synthesis.bs1_values": ("bs1_points",),
    "veribattery.synthesis.pareto": ("Bs1Point", "FrontPoint", "pareto_figure",
                                     "write_pareto_csv", "write_pareto_figure"),
    "veribattery.synthesis.strategy": ("StrategyError", "strategy_frame"),
    "veribattery.synthesis.table_files": ("threshold_json", "write_threshold_csv",
                                          "write_threshold_json"),
    "veribattery.synthesis.thresholds": ("ThresholdRow", "ThresholdTable", "threshold_table"),
}
_HOME = {name: module for module, names in _EXPORTS.items() for name in names}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'veribattery.synthesis' has no attribute {name!r}")
    return getattr(importlib.import_module(_HOME[name]), name)


__all__ = [
    "Bs1Point",
    "FrontPoint",
    "StrategyError",
    "ThresholdRow",
    "ThresholdTable",
    "bs1_least_go_on",
    "bs1_points",
    "pareto_figure",
    "strategy_frame",
    "synthesis_files",
    "threshold_json",
    "threshold_table",
    "unasked_requirements",
    "write_pareto_csv",
    "write_pareto_figure",
    "write_threshold_csv",
    "write_threshold_json",
]
