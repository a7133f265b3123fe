"""BS1's points for the Pareto figure: its P(success) and expected mission time at
several ``safe_t``, from veribattery's own check of BS1's DTMC."""

from __future__ import annotations

import json
from collections.abc import Sequence
from fractions import Fraction

from veribattery.config import MissionConfig, config_to_yaml, load_config
from veribattery.config.exact import show
from veribattery.config.schema import PAPER_PROPERTIES
from veribattery.mission import check_mission
from veribattery.synthesis.pareto import Bs1Point

__all__ = ["bs1_config", "bs1_points"]

_ASKED = ("p_success", "exp_mission_time")


def bs1_points(cfg: MissionConfig, safe_ts: Sequence[Fraction]) -> tuple[Bs1Point, ...]:
    """BS1 on *cfg*'s farm, battery and wind at each of *safe_ts*, in that order.

    :raises VeribatteryError: when a config cannot be built or checked.
    """
    points = []
    for safe_t in safe_ts:
        values = check_mission(bs1_config(cfg, safe_t), keep="answers").values
        points.append(Bs1Point(Fraction(safe_t), float(values["p_success"]),
                               float(values["exp_mission_time"])))
    return tuple(points)


def bs1_config(cfg: MissionConfig, safe_t: Fraction) -> MissionConfig:
    """*cfg* in BS1 mode at *safe_t*, asking only the paper's P(success) and expected
    mission time (whatever *cfg*'s own properties and requirements are)."""
    asked = {name: PAPER_PROPERTIES[name] for name in _ASKED}
    return load_config(config_to_yaml(cfg), [
        "strategy.mode=bs1", f"strategy.safe_t={show(Fraction(safe_t))}",
        f"properties={json.dumps(asked)}", "requirements=[]", "sweep.vary=[]"])
