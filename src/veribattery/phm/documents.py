"""The results of the phm commands as plain data: every number their tables show, unrounded.

Each function returns nested dicts and lists of str, bool, int, float, exact
:class:`~fractions.Fraction` config values and None, in the order the tables show them;
the command line turns that into one JSON object (Fractions as numbers, infinities as
strings).
"""

from __future__ import annotations

import math

from veribattery.phm.fade import FadeReport
from veribattery.phm.forecast import Forecast
from veribattery.phm.levels import LEVELS, WINDS, StepFit
from veribattery.phm.recheck import Recheck, flatten
from veribattery.phm.refit import FadeParameters, LevelParameters

__all__ = ["fade_document", "forecast_document", "levels_document", "recheck_document"]


def fade_document(params: FadeParameters) -> dict[str, object]:
    """Every fit, the choice, and the capacity and fade at the chosen cycle."""
    fit = params.fit
    return {
        "fits": _fits(params.report),
        "skipped": dict(params.report.skipped),
        "model": fit.name,
        "choice": params.report.explanation(),
        "residuals_ah": [float(r) for r in fit.residuals],
        "at_cycle": params.at_cycle,
        "capacity_fit_ah": params.capacity_fit_ah,
        "capacity_ah": params.capacity_ah,
        "loss_ah_per_cycle": fit.loss_per_cycle(params.at_cycle),
        "fade_per_cycle": params.fade,
        "fade_ci95": list(params.fade_ci),
        "fade_per_recharge": params.fade_per_recharge,
        "fragment": flatten(params.fragment.values),
    }


def _fits(report: FadeReport) -> list[dict[str, object]]:
    return [{"model": fit.name, "formula": fit.formula,
             "params": {name: float(value) for name, value in fit.params.items()},
             "aic": fit.aic, "rmse_ah": fit.rmse,
             "max_abs_residual_ah": float(abs(fit.residuals).max())} for fit in report.fits]


def levels_document(params: LevelParameters, config_steps: StepFit | None) -> dict[str, object]:
    """Thresholds, levels, the step error (and the config's own thresholds'), Eq. 2's table.

    :param config_steps: the config's thresholds on the same curve, when they fit it.
    """
    steps = params.steps
    return {
        "thresholds": {"low": steps.low, "high": steps.high},
        "voltages_v": dict(zip(LEVELS, params.voltages_v, strict=True)),
        "rms_v": steps.rms_v,
        "max_v": steps.max_v,
        "config_thresholds": None if config_steps is None else {
            "low": config_steps.low, "high": config_steps.high,
            "rms_v": config_steps.rms_v, "max_v": config_steps.max_v},
        "resolution_ah": params.resolution,
        "consumption_units": {
            action: {wind: dict(zip(LEVELS, row, strict=True))
                     for wind, row in zip(WINDS, rows, strict=True)}
            for action, rows in params.table.items()},
        "fragment": flatten(params.fragment.values),
    }


def forecast_document(result: Forecast) -> dict[str, object]:
    """Every checked age with all property values, and when the requirement stops holding."""
    fails = result.fails_after
    return {
        "requirement": str(result.requirement),
        "now": result.now,
        "points": [{"ahead": p.ahead, "cycle": result.now + p.ahead,
                    "capacity_ah": p.capacity_ah, "fade_per_recharge": p.fade,
                    "values": dict(p.values), "holds": p.holds} for p in result.points],
        "fails_after": fails,
        "fails_at_cycle": None if fails is None else result.now + fails,
    }


def recheck_document(result: Recheck) -> dict[str, object]:
    """What the refit moved, every property before and after, the requirements' verdicts."""
    before_holds = {str(o.requirement): o.holds for o in result.before.requirements}
    after = result.after.values
    return {
        "moved": [{"key": m.key, "before": m.before, "after": m.after} for m in result.moved],
        "properties": {name: {"before": value, "after": after.get(name),
                              "change": _change(value, after.get(name))}
                       for name, value in result.before.values.items()},
        "requirements": [{"requirement": str(o.requirement),
                          "before": before_holds.get(str(o.requirement)),
                          "after": o.holds} for o in result.after.requirements],
        "regressions": list(result.regressions),
        "warnings": list(result.after.warnings),
    }


def _change(before: object, after: object) -> float | None:
    """``after - before`` for two numbers, else None (booleans are not numbers here, and an
    undefined value, NaN, has no change)."""
    if isinstance(before, bool) or isinstance(after, bool):
        return None
    if isinstance(before, int | float) and isinstance(after, int | float):
        change = float(after) - float(before)
        return None if math.isnan(change) else change  # undefined on one side: no change
    return None
