"""The phm package's public API is exactly its __all__, and it never imports the engine
modules itself (only through the mission/sweep facades)."""

from __future__ import annotations

import ast
from pathlib import Path

import veribattery.phm as phm

EXPECTED = {
    "AgePoint", "BeyondDataError", "CycleLog", "DischargeCurve", "FadeFit", "FadeParameters",
    "FadeReport", "Forecast", "Fragment", "LevelParameters", "PhmDataError", "RechargeCapError",
    "Recheck", "Refit",
    "StepFit",
    "coulomb_count", "eq2_table", "fade_parameters", "fit_all", "fit_steps", "forecast",
    "level_parameters", "merge_text", "read_cycles", "read_discharge", "recheck", "refit",
    "write_atomic",
}
ENGINE = ("veribattery.lang", "veribattery.explore", "veribattery.checker",
          "veribattery.pipeline", "veribattery.render", "veribattery.cli", "click")


def test_all_is_the_curated_api() -> None:
    assert set(phm.__all__) == EXPECTED
    for name in phm.__all__:
        assert getattr(phm, name) is not None


def test_phm_imports_no_engine_module() -> None:
    paths = sorted(Path(phm.__file__).parent.glob("*.py"))
    assert len(paths) > 1, "no phm modules found: nothing was checked"
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            for name in names:
                assert not name.startswith(ENGINE), f"{path.name} imports {name}"
