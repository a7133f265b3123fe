"""Battery prognostics in the loop: PHM data → the battery keys of a mission config.

This layer imports the config layer (and, for :func:`recheck` and :func:`forecast`,
the mission and sweep facades), never the engine. scipy, matplotlib and PyBaMM are
imported inside the functions that need them::

    log = read_cycles("cycles.csv")
    params = fade_parameters(log, load_config("mission.yaml"))   # capacity_ah, fade
    print(params.fragment.yaml())
"""

from __future__ import annotations

from veribattery.phm.data import (
    CycleLog,
    DischargeCurve,
    PhmDataError,
    coulomb_count,
    read_cycles,
    read_discharge,
)
from veribattery.phm.fade import FadeFit, FadeReport, fit_all
from veribattery.phm.forecast import AgePoint, Forecast, forecast
from veribattery.phm.fragment import Fragment
from veribattery.phm.levels import StepFit, eq2_table, fit_steps
from veribattery.phm.merge import merge_text, write_atomic
from veribattery.phm.recheck import Recheck, Refit, recheck, refit
from veribattery.phm.refit import (
    BeyondDataError,
    FadeParameters,
    LevelParameters,
    RechargeCapError,
    fade_parameters,
    level_parameters,
)

__all__ = [
    "AgePoint",
    "BeyondDataError",
    "CycleLog",
    "DischargeCurve",
    "FadeFit",
    "FadeParameters",
    "FadeReport",
    "Forecast",
    "Fragment",
    "LevelParameters",
    "PhmDataError",
    "RechargeCapError",
    "Recheck",
    "Refit",
    "StepFit",
    "coulomb_count",
    "eq2_table",
    "fade_parameters",
    "fit_all",
    "fit_steps",
    "forecast",
    "level_parameters",
    "merge_text",
    "read_cycles",
    "read_discharge",
    "recheck",
    "refit",
    "write_atomic",
]
