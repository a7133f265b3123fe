"""The paper's proposed loop: refit the battery from the newest data, re-verify, compare.

:func:`recheck` checks the mission as configured and again with the refitted battery
keys, and lists which parameter moved and which requirement stopped holding.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from veribattery.config import MissionConfig, consumption_units, load_config
from veribattery.mission import MissionReport, MissionSession
from veribattery.phm.data import read_cycles, read_discharge
from veribattery.phm.fragment import Fragment
from veribattery.phm.refit import FadeParameters, LevelParameters, fade_parameters, level_parameters

__all__ = ["Moved", "Recheck", "Refit", "flatten", "recheck", "refit"]


@dataclass(frozen=True, slots=True)
class Refit:
    """The refitted battery: fade (always) and levels (when a discharge curve is given)."""

    fade: FadeParameters
    levels: LevelParameters | None

    @property
    def fragment(self) -> Fragment:
        """Every refitted config key."""
        values = dict(self.fade.fragment.values)
        if self.levels is not None:
            values.update(self.levels.fragment.values)
        return Fragment(values)


def refit(cfg: MissionConfig, cycles: str | Path, discharge: str | Path | None = None,
          model: str | None = None) -> Refit:
    """Fit the battery keys of *cfg* from a capacity log and, optionally, a discharge log."""
    fade = fade_parameters(read_cycles(cycles), cfg, model=model)
    levels = None
    if discharge is not None:
        levels = level_parameters(read_discharge(discharge), cfg)
    return Refit(fade, levels)


@dataclass(frozen=True, slots=True)
class Moved:
    """A config key whose value the refit changed (``before`` None: it was not set so)."""

    key: str
    before: object
    after: object


@dataclass(frozen=True, slots=True)
class Recheck:
    """Both verifications and what changed between them."""

    refit: Refit
    before: MissionReport
    after: MissionReport
    moved: tuple[Moved, ...]

    @property
    def regressions(self) -> tuple[str, ...]:
        """Requirements that held before the refit and no longer hold."""
        held = {str(o.requirement) for o in self.before.requirements if o.holds}
        return tuple(str(o.requirement) for o in self.after.requirements
                     if not o.holds and str(o.requirement) in held)


def flatten(values: dict[str, object]) -> dict[str, object]:
    """Nested mappings under dotted keys → one dotted key per leaf."""
    flat: dict[str, object] = {}
    for key, value in values.items():
        if isinstance(value, dict):
            flat.update(flatten({f"{key}.{k}": v for k, v in value.items()}))
        else:
            flat[key] = value
    return flat


def _current(cfg: MissionConfig, key: str) -> object:
    node: object = cfg
    for part in key.split("."):
        node = getattr(node, part, None)
        if node is None:
            return None
    return node


def _moved(before: MissionConfig, after: MissionConfig, fragment: Fragment) -> list[Moved]:
    moved = []
    for key, value in flatten(fragment.values).items():
        old = _current(before, key)
        if old != value:
            moved.append(Moved(key, old, value))
    old_units, new_units = consumption_units(before.battery), consumption_units(after.battery)
    for action in ("takeoff_land", "cell", "inspection"):
        if old_units.of(action) != new_units.of(action):
            moved.append(Moved(f"consumption units ({action}) [wind][level]",
                               old_units.of(action), new_units.of(action)))
    return moved


def recheck(config: str | Path, cycles: str | Path, discharge: str | Path | None = None,
            overrides: Sequence[str] = (), model: str | None = None,
            session: MissionSession | None = None) -> Recheck:
    """Verify *config* as it is and with the battery refitted from the data.

    :param session: what checks both configs (default: a
        :class:`~veribattery.mission.MissionSession` that keeps every state's values and
        re-uses the first config's state space for the second where it can).
    :raises VeribatteryError: on bad config or data (before anything is checked).
    """
    before_cfg = load_config(config, overrides)
    fitted = refit(before_cfg, cycles, discharge, model)
    after_cfg = load_config(config, [*overrides, *fitted.fragment.overrides()])
    session = session or MissionSession()
    before, after = session.check(before_cfg), session.check(after_cfg)
    return Recheck(fitted, before, after, tuple(_moved(before_cfg, after_cfg, fitted.fragment)))
