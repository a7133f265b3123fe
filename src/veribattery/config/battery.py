"""Battery arithmetic in integer units of ``resolution_ah``: capacity and consumption table.

Index conventions, used everywhere below and in the template: wind ``0`` low / ``1``
high; voltage level ``0`` low / ``1`` medium / ``2`` high.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

from veribattery.config.schema import (
    BatteryConfig,
    ConsumptionEq2,
    ConsumptionTable,
    LevelValues,
)

__all__ = [
    "ACTIONS",
    "FIXED_LEVEL",
    "CostTable",
    "capacity_units",
    "consumption_units",
    "round_half_up",
]

ACTIONS = ("takeoff_land", "cell", "inspection")
FIXED_LEVEL = {"basic_low": 0, "basic_medium": 1, "basic_high": 2}

Levels = tuple[int, int, int]


def round_half_up(value: Fraction) -> int:
    """Round to the nearest integer, halves upwards (``2.5 → 3``), exactly."""
    return math.floor(value + Fraction(1, 2))


@dataclass(frozen=True, slots=True)
class CostTable:
    """Units consumed per action, indexed ``[wind][level]``.

    :ivar takeoff_land: one take-off or one landing.
    :ivar cell: flying across one cell.
    :ivar inspection: inspecting one turbine.
    """

    takeoff_land: tuple[Levels, Levels]
    cell: tuple[Levels, Levels]
    inspection: tuple[Levels, Levels]

    def of(self, action: str) -> tuple[Levels, Levels]:
        """The ``[wind][level]`` costs of *action* (one of :data:`ACTIONS`)."""
        costs: tuple[Levels, Levels] = getattr(self, action)
        return costs


def capacity_units(battery: BatteryConfig) -> int:
    """``C_NEW``: the new battery's capacity in units (validated to be whole)."""
    units = battery.capacity_ah / battery.resolution_ah
    return units.numerator // units.denominator


def _levels(values: LevelValues) -> tuple[Fraction, Fraction, Fraction]:
    return (values.low, values.medium, values.high)


def _from_table(table: ConsumptionTable, resolution: Fraction) -> CostTable:
    """Low wind: Table 2 in units; high wind: each unit entry x factor, rounded half up."""

    def row(values: LevelValues) -> tuple[Levels, Levels]:
        low = tuple(round_half_up(v / resolution) for v in _levels(values))
        high = tuple(round_half_up(u * table.high_wind_factor) for u in low)
        return (low, high)  # type: ignore[return-value]

    return CostTable(row(table.takeoff_land), row(table.cell), row(table.inspection))


def _from_eq2(eq2: ConsumptionEq2, resolution: Fraction) -> CostTable:
    """Eq. 2, ``C = E_spec·t / (V·T)``, for every wind and level, rounded half up to units."""
    times = eq2.action_time_h
    flight = (eq2.flight_time_h.low_wind, eq2.flight_time_h.high_wind)

    def row(t: Fraction) -> tuple[Levels, Levels]:
        return tuple(  # type: ignore[return-value]
            tuple(round_half_up(eq2.energy_wh * t / (v * f) / resolution)
                  for v in _levels(eq2.voltages_v))
            for f in flight
        )

    return CostTable(row(times.takeoff_land), row(times.cell), row(times.inspection))


def consumption_units(battery: BatteryConfig) -> CostTable:
    """The consumption table in units, from Table 2 or from Eq. 2's parameters."""
    consumption = battery.consumption
    if isinstance(consumption, ConsumptionEq2):
        return _from_eq2(consumption, battery.resolution_ah)
    return _from_table(consumption, battery.resolution_ah)
