"""What checking one sweep point gives back: plain numbers and strings only (never the
model), so that it pickles small on its way from a worker."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["PointResult", "PropertyValue"]


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
