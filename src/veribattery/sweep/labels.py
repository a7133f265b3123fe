"""Readable axis labels for sweep figures: config keys and properties, with their units.

Units are those of the config schema (``configs/example.yaml``): Ah for capacities,
resolutions and consumptions, minutes for ``times_min.*``, metres, volts, hours and Wh
for Eq. 2's parameters. An unknown key or property keeps its raw name.
"""

from __future__ import annotations

from veribattery.config.schema import PAPER_PROPERTIES

__all__ = ["KEY_LABELS", "PROPERTY_LABELS", "key_label", "property_label"]

_ACTIONS = {"takeoff_land": "take-off/landing", "cell": "cell crossing",
            "inspection": "inspection"}
_LEVELS = ("low", "medium", "high")

#: Config keys (as ``--vary`` takes them) and their labels.
KEY_LABELS: dict[str, str] = {
    "farm.cols": "farm columns (turbines)",
    "farm.rows": "farm rows (turbines)",
    "farm.spacing_m": "turbine spacing (m)",
    "farm.base": "base cell",
    "farm.route": "route",
    "battery.model": "battery model",
    "battery.capacity_ah": "battery capacity (Ah)",
    "battery.resolution_ah": "charge resolution (Ah)",
    "battery.fade_per_recharge": "capacity fade per recharge",
    "battery.max_recharges": "recharge cap (recharges)",
    "battery.voltage_thresholds.high": "high-voltage SOC threshold",
    "battery.voltage_thresholds.low": "low-voltage SOC threshold",
    "battery.consumption.high_wind_factor": "high-wind consumption factor",
    "battery.consumption.energy_wh": "battery energy (Wh)",
    "battery.consumption.flight_time_h.low_wind": "flight time, low wind (h)",
    "battery.consumption.flight_time_h.high_wind": "flight time, high wind (h)",
    "strategy.safe_t": "safety threshold safe_t (SOC)",
    "environment.p_wsp_c": "P(wind change per action)",
    "times_min.takeoff_land": "take-off/landing time (min)",
    "times_min.per_cell": "time per cell (min)",
    "times_min.inspection": "inspection time (min)",
    "times_min.recharge": "recharge time (min)",
    "times_min.wait": "waiting time per step (min)",
    **{f"battery.consumption.{action}.{level}": f"{text} consumption, {level} voltage (Ah)"
       for action, text in _ACTIONS.items() for level in _LEVELS},
    **{f"battery.consumption.voltages_v.{level}": f"{level} voltage (V)" for level in _LEVELS},
    **{f"battery.consumption.action_time_h.{action}": f"{text} time (h)"
       for action, text in _ACTIONS.items()},
}

#: The paper's properties (``PAPER_PROPERTIES``) and their labels.
PROPERTY_LABELS: dict[str, str] = {
    "p_success": "P(success)",
    "exp_mission_time": "expected mission time (min)",
    "exp_recharges": "expected recharges",
    "exp_mission_time_given_success": "expected mission time given success (min)",
    "exp_recharges_given_success": "expected recharges given success",
    "p_success_max": "Pmax(success), best return policy",
    "p_success_max_lower": "Pmax(success), certified lower end",
    "p_success_max_upper": "Pmax(success), certified upper end",
}


def key_label(key: str) -> str:
    """``battery.capacity_ah`` → ``battery capacity (Ah)``; an unknown key as it is."""
    return KEY_LABELS.get(key, key)


def property_label(name: str, formula: str | None = None) -> str:
    """``p_success`` → ``P(success)``; an unknown property as it is.

    :param formula: the property's PRISM text, when known: a paper property's label is
        used only if *formula* is the paper's (a config may give the name another meaning).
    """
    label = PROPERTY_LABELS.get(name)
    paper = PAPER_PROPERTIES.get(name)
    if label is None or (formula is not None and paper is not None
                         and _squash(formula) != _squash(paper)):
        return name
    return label


def _squash(text: str) -> str:
    return "".join(text.split())
