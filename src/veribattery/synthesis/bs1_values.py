"""BS1 beside the optimum: its P(success), expected mission time and recharges at the
config's ``safe_t``, and its points for the Pareto figure at several ``safe_t``, from
veribattery's own check of BS1's DTMC."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

from veribattery.checker import CheckResult
from veribattery.config import MissionConfig, config_to_yaml, load_config
from veribattery.config.exact import show
from veribattery.config.schema import PAPER_PROPERTIES
from veribattery.mission import check_mission
from veribattery.pipeline import ProgressCallback
from veribattery.synthesis.model import Certified
from veribattery.synthesis.pareto import Bs1Point

__all__ = ["Bs1Values", "bs1_config", "bs1_points", "bs1_values"]

_ASKED = ("p_success", "exp_mission_time")
_COMPARED = ("p_success", "exp_mission_time", "exp_recharges")


@dataclass(frozen=True, slots=True)
class Bs1Values:
    """BS1 at one *safe_t*: its certified P(success), expected mission time and
    expected recharges (failed missions included), and its DTMC's size."""

    safe_t: Fraction
    p_success: Certified
    exp_mission_time: Certified
    exp_recharges: Certified
    states: int


def bs1_values(cfg: MissionConfig, *, progress: ProgressCallback | None = None) -> Bs1Values:
    """BS1 on *cfg*'s farm, battery and wind at *cfg*'s own ``safe_t``.

    :raises VeribatteryError: when the config cannot be built or checked.
    """
    safe_t = Fraction(cfg.strategy.safe_t)
    report = check_mission(bs1_config(cfg, safe_t, _COMPARED), keep="answers",
                           progress=progress)
    found = {r.property.name: r for r in report.run.results}
    p_success, time, recharges = (_certified(found[name]) for name in _COMPARED)
    return Bs1Values(safe_t, p_success, time, recharges, report.run.dtmc.num_states)


def _certified(result: CheckResult) -> Certified:
    value = float(result.value)
    lower, upper = result.lower, result.upper
    return Certified(value, value if lower is None else float(lower),
                     value if upper is None else float(upper))


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


def bs1_config(cfg: MissionConfig, safe_t: Fraction,
               names: Sequence[str] = _ASKED) -> MissionConfig:
    """*cfg* in BS1 mode at *safe_t*, asking only the paper's properties *names* (by
    default P(success) and expected mission time), whatever *cfg*'s own properties and
    requirements are."""
    asked = {name: PAPER_PROPERTIES[name] for name in names}
    return load_config(config_to_yaml(cfg), [
        "strategy.mode=bs1", f"strategy.safe_t={show(Fraction(safe_t))}",
        f"properties={json.dumps(asked)}", "requirements=[]", "sweep.vary=[]"])
