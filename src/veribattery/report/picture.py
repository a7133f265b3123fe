"""The mission as a picture: the farm and route, and the battery model, as the model has them.

The farm comes from the derived layout the template renders (route order, turbines
per cell); the capacity after each recharge is the rendered model's own ``cap``
formula evaluated at every ``rc``, so the picture and the model cannot disagree.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from veribattery.analyses.mission_view import WINDS, MissionModel
from veribattery.config import ModelParameters, derive_parameters
from veribattery.config.battery import ACTIONS
from veribattery.explore import compile_expr
from veribattery.report.data import Battery, ConsumptionRow, Farm

__all__ = ["ACTION_NAMES", "battery_picture", "farm_picture"]

#: The consumption table's actions in words.
ACTION_NAMES = {"takeoff_land": "take-off or landing", "cell": "flying one cell",
                "inspection": "inspecting one turbine"}


def farm_picture(mission: MissionModel) -> Farm:
    """The farm grid, base and route of *mission*."""
    cfg = mission.config
    layout = derive_parameters(cfg).layout
    route = cfg.farm.route if isinstance(cfg.farm.route, str) else "a list of cells"
    return Farm(
        cols=layout.cols, rows=layout.rows, spacing_m=float(cfg.farm.spacing_m),
        base=(int(layout.base[0]), int(layout.base[1])), route_name=str(route),
        route=tuple((int(x), int(y)) for x, y in layout.route), turbines=layout.n,
        appointed=tuple(((int(t[0]), int(t[1])), (int(c[0]), int(c[1])))
                        for t, c in layout.appointed),
    )


def battery_picture(mission: MissionModel) -> Battery:
    """The battery model of *mission*: fade, voltage levels, consumption, action times."""
    cfg = mission.config
    params = derive_parameters(cfg)
    resolution = Fraction(cfg.battery.resolution_ah)
    return Battery(
        model=params.model,
        new_capacity_ah=float(cfg.battery.capacity_ah),
        resolution_ah=float(resolution),
        fade_per_recharge=float(cfg.battery.fade_per_recharge) if params.model == "advanced"
        else 0.0,
        max_recharges=params.rc_max,
        capacity_ah=_capacity_by_recharges(mission, params, resolution),
        level_high=params.v_high.num / params.v_high.den,
        level_low=params.v_low.num / params.v_low.den,
        safe_t=params.safe.num / params.safe.den,
        p_wind_change=float(params.p_wsp_c),
        consumption=_consumption(params, resolution),
        consumption_source=params.cost_source,
        times_min=tuple((name, float(value)) for name, value in params.times.items()),
    )


def _capacity_by_recharges(mission: MissionModel, params: ModelParameters,
                           resolution: Fraction) -> tuple[float, ...]:
    """The model's ``cap`` formula at ``rc = 0 .. RC_MAX`` (other variables 0), in Ah."""
    names = mission.dtmc.variable_names
    formulas = {f.name: f.expr for f in mission.flat.formulas}
    rows = np.zeros((params.rc_max + 1, len(names)), dtype=np.int64)
    rows[:, names.index("rc")] = np.arange(params.rc_max + 1)
    units = np.broadcast_to(np.asarray(compile_expr(formulas["cap"], names)(rows)),
                            (rows.shape[0],))
    return tuple(float(int(u) * resolution) for u in units)


def _consumption(params: ModelParameters, resolution: Fraction) -> tuple[ConsumptionRow, ...]:
    """Each action's cost at each wind, by voltage level, in Ah (the cost table's level
    order: low, medium, high, as ``mission_view.LEVELS``)."""
    rows = []
    for action in ACTIONS:
        costs = params.costs.of(action)
        for wind, name in enumerate(WINDS):
            low, medium, high = (float(units * resolution) for units in costs[wind])
            rows.append(ConsumptionRow(ACTION_NAMES[action], name, (low, medium, high)))
    return tuple(rows)

