"""Verification as the battery ages: the mission checked at future cycles of the fade fit.

At ``n`` cycles from now the new capacity is the fit's ``C(N + n)`` (on the
``resolution_ah`` grid) and the fade per recharge the fit's relative slope there. Each
age is checked through the sweep machinery (:func:`veribattery.sweep.run_sweep`, one
point each, since capacity and fade move together rather than on a product grid).
Ages that round to the same config are checked once. Between the last age meeting the
requirement and the first failing it, bisection finds the exact cycle.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

from veribattery.config import MissionConfig, Requirement, load_config
from veribattery.phm.data import CycleLog, PhmDataError
from veribattery.phm.fade import choose
from veribattery.phm.fragment import Fragment
from veribattery.phm.refit import FadeParameters, parameters_at

__all__ = ["AgePoint", "Forecast", "forecast", "grid_ages"]

#: Called before each age is checked with (its number from 1, the number of grid ages or
#: 0 for an age the bisection adds, its cycle).
ForecastProgress = Callable[[int, int, float], None]


@dataclass(frozen=True, slots=True)
class AgePoint:
    """The mission at one age.

    :ivar ahead: cycles from the last logged one.
    :ivar capacity_ah: the new capacity used (on the grid).
    :ivar fade: the fade per recharge used.
    :ivar values: property name → value.
    :ivar holds: whether the requirement holds.
    """

    ahead: int
    capacity_ah: Fraction
    fade: Fraction
    values: dict[str, object]
    holds: bool


@dataclass(frozen=True, slots=True)
class Forecast:
    """Every checked age, in order, and when the requirement stops holding.

    :ivar now: the last logged cycle.
    :ivar requirement: the requirement judged.
    :ivar points: checked ages, by ``ahead``.
    :ivar fails_after: the first age (cycles ahead) at which it fails, None if never
        within the horizon; exact to one cycle when bisection ran.
    """

    now: float
    requirement: Requirement
    points: tuple[AgePoint, ...]
    fails_after: int | None


def grid_ages(horizon: int, step: int) -> list[int]:
    """``0, step, 2·step, …`` and *horizon* itself."""
    ages = list(range(0, horizon + 1, step))
    return ages if ages[-1] == horizon else [*ages, horizon]


class _Ager:
    """Checks ages, caching by the config values they round to."""

    def __init__(self, config: str | Path, log: CycleLog, cfg: MissionConfig,
                 overrides: Sequence[str], model: str | None) -> None:
        self.config, self.log, self.cfg = config, log, cfg
        self.overrides = list(overrides)
        # Fitted once: every age reads the same fit (a refit took 0.08 s per age).
        self.report, self.fit = choose(log, model)
        self.cache: dict[tuple[object, ...], dict[str, object]] = {}

    def parameters(self, ahead: int) -> FadeParameters:
        return parameters_at(self.log, self.report, self.fit, self.cfg,
                             float(self.log.cycle[-1]) + ahead)

    def values(self, fragment: Fragment) -> dict[str, object]:
        from veribattery.sweep import run_sweep

        key = tuple(fragment.values.values())
        if key not in self.cache:
            frame = run_sweep(self.config, [], [*self.overrides, *fragment.overrides()])
            self.cache[key] = dict(zip(frame["property"], frame["value"], strict=True))
        return self.cache[key]


def forecast(config: str | Path, log: CycleLog, requirement: Requirement, horizon: int,
             step: int, overrides: Sequence[str] = (), model: str | None = None,
             progress: ForecastProgress | None = None) -> Forecast:
    """Check the mission at ages ``0..horizon`` (every *step*), then bisect the crossing.

    :raises BeyondDataError: when the fit gives no usable values at some age (too far
        beyond the log: the exception says how far it does).
    :raises PhmDataError: when the fit is not meaningful at the log's last cycle.
    :raises ConfigError: when the config (or an age's values) does not validate.
    """
    cfg = load_config(config, overrides)
    if requirement.prop not in cfg.properties:
        raise PhmDataError(f"requirement {requirement}: unknown property {requirement.prop!r} "
                           f"(declared: {', '.join(cfg.properties)})")
    ager = _Ager(config, log, cfg, overrides, model)
    points: dict[int, AgePoint] = {}
    ages = grid_ages(horizon, step)

    def visit(ahead: int) -> AgePoint:
        if ahead not in points:
            if progress is not None:
                progress(len(points) + 1, len(ages) if ahead in ages else 0,
                         float(log.cycle[-1]) + ahead)
            params = ager.parameters(ahead)
            values = ager.values(params.fragment)
            holds = requirement.holds(float(values[requirement.prop]))  # type: ignore[arg-type]
            points[ahead] = AgePoint(ahead, params.capacity_ah, params.fade_per_recharge,
                                     values, holds)
        return points[ahead]

    for ahead in ages:
        visit(ahead)
    fails = _first_failure(ages, visit)
    return Forecast(float(log.cycle[-1]), requirement,
                    tuple(points[a] for a in sorted(points)), fails)


def _first_failure(ages: list[int], visit: Callable[[int], AgePoint]) -> int | None:
    """The first grid age that fails, narrowed by bisection from the age before it."""
    failing = [a for a in ages if not visit(a).holds]
    if not failing:
        return None
    bad = failing[0]
    if bad == ages[0]:
        return bad
    good = ages[ages.index(bad) - 1]
    while bad - good > 1:
        middle = (good + bad) // 2
        if visit(middle).holds:
            good = middle
        else:
            bad = middle
    return bad
