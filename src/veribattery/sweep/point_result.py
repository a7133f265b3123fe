"""What checking one sweep point gives back: plain numbers and strings only (never the
model), so that it pickles small on its way from a worker."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from veribattery.config import MissionConfig

__all__ = ["SYNTHESIS_PROPERTIES", "PointResult", "PropertyValue", "point_properties"]

_PMAX = 'Pmax=? [ F "success" ]'
#: The rows of a synthesis point, in order (``Pmax`` and its certified interval's ends),
#: and what each is of.
SYNTHESIS_PROPERTIES = {"p_success_max": _PMAX, "p_success_max_lower": _PMAX,
                        "p_success_max_upper": _PMAX}


@dataclass(frozen=True, slots=True)
class PropertyValue:
    """One property's value at a point, with the requirements on it and their verdict."""

    name: str
    value: float | bool
    requirement: str | None
    holds: bool | None


@dataclass(frozen=True, slots=True)
class PointResult:
    """The outcome of checking one grid point (*error* set, and no values, if it failed)."""

    index: int
    values: tuple[PropertyValue, ...] = ()
    states: int | None = None
    transitions: int | None = None
    seconds: float = 0.0
    recharge_cap_probability: float | None = None
    warnings: tuple[str, ...] = ()
    error: str | None = None


def point_properties(cfg: MissionConfig) -> tuple[str, ...]:
    """The properties a point of *cfg* gives one row each, in order: the config's, or
    in synthesis mode :data:`SYNTHESIS_PROPERTIES` (a point that failed gives one row)."""
    if cfg.strategy.mode == "synthesize":
        return tuple(SYNTHESIS_PROPERTIES)
    return tuple(cfg.properties)
