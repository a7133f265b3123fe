"""veribattery: verify battery-powered robot missions with an in-repo PRISM DTMC model checker.

The pipeline, stage by stage (each a pure function)::

    model = parse_model(Path("examples/prism/dice.pm"))
    dtmc = build_dtmc(flatten_model(model))  # constants: flatten_model(model, {"N": 3})
    result = check(dtmc, parse_property("P=? [ F s=7 & d=6 ]"))
    result.value  # 0.16666666666666666

and for missions::

    report = check_mission(load_config("configs/paper/case1.yaml"))
    report.values["p_success"]  # 1.0

One typed entry point per way of checking: :func:`check_model` (floating point,
certified bounds), :func:`check_model_exact` (rational arithmetic), and a
:class:`Session` (or, for missions, a :class:`MissionSession`) for many similar models
in a row; :class:`CheckOptions` says what each result keeps.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from veribattery.checker import CheckResult, check
    from veribattery.config import MissionConfig, load_config
    from veribattery.errors import (
        CheckError,
        ConfigError,
        ModelError,
        PrismSemanticError,
        PrismSyntaxError,
        RenderError,
        VeribatteryError,
    )
    from veribattery.explore import DTMC, build_dtmc
    from veribattery.lang import (
        flatten_model,
        parse_model,
        parse_properties,
        parse_property,
        resolve_property,
    )
    from veribattery.mission import MissionReport, MissionSession, check_mission, mission_files
    from veribattery.pipeline import (
        CheckOptions,
        ModelCheckRun,
        Session,
        check_model,
        check_model_exact,
        check_prism_file,
    )
    from veribattery.render import render_model, render_properties
    from veribattery.sweep import run_sweep


# Exports are imported on first use, so `import veribattery` (and the CLI's start-up)
# does not pay for numpy, scipy, pydantic and Jinja until a stage needs them.
_EXPORTS = {
    "veribattery.checker": ("CheckResult", "check"),
    "veribattery.config": ("MissionConfig", "load_config"),
    "veribattery.errors": (
        "CheckError", "ConfigError", "ModelError", "PrismSemanticError",
        "PrismSyntaxError", "RenderError", "VeribatteryError",
    ),
    "veribattery.explore": ("DTMC", "build_dtmc"),
    "veribattery.lang": (
        "flatten_model", "parse_model", "parse_properties", "parse_property", "resolve_property",
    ),
    "veribattery.mission": ("MissionReport", "MissionSession", "check_mission", "mission_files"),
    "veribattery.pipeline": ("CheckOptions", "ModelCheckRun", "Session", "check_model",
                             "check_model_exact", "check_prism_file"),
    "veribattery.render": ("render_model", "render_properties"),
    "veribattery.sweep": ("run_sweep",),
}
_HOME = {name: module for module, names in _EXPORTS.items() for name in names}


def __getattr__(name: str) -> Any:
    if name == "__version__":  # written once, in pyproject.toml; read when asked for
        from importlib.metadata import version

        return version("veribattery")
    if name not in _HOME:
        raise AttributeError(f"module 'veribattery' has no attribute {name!r}")
    return getattr(importlib.import_module(_HOME[name]), name)


__all__ = [
    "DTMC",
    "CheckError",
    "CheckOptions",
    "CheckResult",
    "ConfigError",
    "MissionConfig",
    "MissionReport",
    "MissionSession",
    "ModelCheckRun",
    "ModelError",
    "PrismSemanticError",
    "PrismSyntaxError",
    "RenderError",
    "Session",
    "VeribatteryError",
    "build_dtmc",
    "check",
    "check_mission",
    "check_model",
    "check_model_exact",
    "check_prism_file",
    "flatten_model",
    "load_config",
    "mission_files",
    "parse_model",
    "parse_properties",
    "parse_property",
    "render_model",
    "render_properties",
    "resolve_property",
    "run_sweep",
]
