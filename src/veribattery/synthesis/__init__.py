"""Synthesis: the mission as an MDP (model-spec.md, "Synthesis"), its files and questions,
and what a synthesised strategy means in the mission's words.

Modules: :mod:`~veribattery.synthesis.files` (what ``emit`` writes),
:mod:`~veribattery.synthesis.strategy` (a strategy state by state, the tables' input),
:mod:`~veribattery.synthesis.decisions` (where the drone decides to go on),
:mod:`~veribattery.synthesis.levels` (voltage levels per state),
:mod:`~veribattery.synthesis.bs1_rule` (BS1's rule as a charge threshold),
:mod:`~veribattery.synthesis.thresholds` (the threshold table) and
:mod:`~veribattery.synthesis.table_files` (its CSV and JSON),
:mod:`~veribattery.synthesis.pareto` (the Pareto front's figure and CSV),
:mod:`~veribattery.synthesis.bs1_values` (BS1's values and its points on it),
:mod:`~veribattery.synthesis.model` (the MDP built by veribattery's engine),
:mod:`~veribattery.synthesis.optimal` (the safest, then fastest strategy),
:mod:`~veribattery.synthesis.exports` (its strategy and induced DTMC as files),
:mod:`~veribattery.synthesis.fastest` (the fastest strategy safe enough, certified:
weighted sums over the Pareto front) and :mod:`~veribattery.synthesis.session`
(:func:`synthesize`, what ``veribattery synthesize`` prints).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from veribattery._lazy import lazy_exports
from veribattery.synthesis.files import synthesis_files, unasked_requirements

if TYPE_CHECKING:
    from veribattery.synthesis.bs1_rule import bs1_least_go_on
    from veribattery.synthesis.bs1_values import Bs1Values, bs1_points, bs1_values
    from veribattery.synthesis.fastest import Fastest, as_safe_as, required_at_least
    from veribattery.synthesis.model import Certified, ModelSize, mission_mdp
    from veribattery.synthesis.optimal import ChosenStrategy
    from veribattery.synthesis.pareto import (
        Bs1Point,
        FrontPoint,
        pareto_figure,
        write_pareto_csv,
        write_pareto_figure,
    )
    from veribattery.synthesis.session import (
        FrontRequest,
        SynthesisResult,
        config_requirements,
        synthesize,
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
    "veribattery.synthesis.bs1_values": ("Bs1Values", "bs1_points", "bs1_values"),
    "veribattery.synthesis.fastest": ("Fastest", "as_safe_as", "required_at_least"),
    "veribattery.synthesis.model": ("Certified", "ModelSize", "mission_mdp"),
    "veribattery.synthesis.optimal": ("ChosenStrategy",),
    "veribattery.synthesis.session": ("FrontRequest", "SynthesisResult", "config_requirements",
                                      "synthesize"),
    "veribattery.synthesis.pareto": ("Bs1Point", "FrontPoint", "pareto_figure",
                                     "write_pareto_csv", "write_pareto_figure"),
    "veribattery.synthesis.strategy": ("StrategyError", "strategy_frame"),
    "veribattery.synthesis.table_files": ("threshold_json", "write_threshold_csv",
                                          "write_threshold_json"),
    "veribattery.synthesis.thresholds": ("ThresholdRow", "ThresholdTable", "threshold_table"),
}
__getattr__ = lazy_exports(__name__, _EXPORTS)


__all__ = [
    "Bs1Point",
    "Bs1Values",
    "Certified",
    "ChosenStrategy",
    "Fastest",
    "FrontPoint",
    "FrontRequest",
    "ModelSize",
    "StrategyError",
    "SynthesisResult",
    "ThresholdRow",
    "ThresholdTable",
    "as_safe_as",
    "bs1_least_go_on",
    "bs1_points",
    "bs1_values",
    "config_requirements",
    "mission_mdp",
    "pareto_figure",
    "required_at_least",
    "strategy_frame",
    "synthesis_files",
    "synthesize",
    "threshold_json",
    "threshold_table",
    "unasked_requirements",
    "write_pareto_csv",
    "write_pareto_figure",
    "write_threshold_csv",
    "write_threshold_json",
]
