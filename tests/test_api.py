"""The public API: exactly what __all__ lists, each name importable, lazily loaded."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import veribattery

EXPECTED = {
    "DTMC", "CheckError", "CheckOptions", "CheckResult", "ConfigError", "MissionConfig",
    "MissionReport", "MissionSession", "ModelCheckRun", "ModelError", "PrismSemanticError",
    "PrismSyntaxError", "RenderError", "Session", "VeribatteryError", "build_dtmc", "check",
    "check_mission", "check_model", "check_model_exact", "check_prism_file",
    "flatten_model", "load_config", "mission_files", "parse_model", "parse_properties",
    "parse_property", "render_model", "render_properties", "resolve_property", "run_sweep",
}


def test_all_is_the_curated_api() -> None:
    assert set(veribattery.__all__) == EXPECTED
    for name in veribattery.__all__:
        assert getattr(veribattery, name) is not None


def test_the_pipeline_through_the_api() -> None:
    model = veribattery.parse_model(
        "dtmc\nmodule coin\n  x : [0..2] init 0;\n"
        "  [] x=0 -> 0.5:(x'=1) + 0.5:(x'=2);\n  [] x>0 -> true;\nendmodule\n"
    )
    dtmc = veribattery.build_dtmc(veribattery.flatten_model(model))
    result = veribattery.check(dtmc, veribattery.parse_property("P=? [ F x=2 ]"))
    assert (dtmc.num_states, dtmc.num_transitions) == (3, 4)
    assert result.value == 0.5


def test_errors_share_one_base() -> None:
    for name in ("CheckError", "ConfigError", "ModelError", "PrismSemanticError",
                 "PrismSyntaxError", "RenderError"):
        assert issubclass(getattr(veribattery, name), veribattery.VeribatteryError)


def test_import_is_light() -> None:
    """`import veribattery` loads none of the heavy dependencies until a name is used."""
    code = (
        "import sys, veribattery; "
        "heavy = ('numpy', 'scipy', 'pydantic', 'jinja2', 'pandas', 'matplotlib'); "
        "print(sorted(m for m in heavy if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=Path(__file__).parent)
    assert out.stdout.strip() == "[]"
