"""Capacity and voltage level of the mission's battery, per state, in exact integers.

The MDP has no voltage-level variable: the level is a function of the charge ``b`` and
the recharge count ``rc`` (model-spec.md, "The battery"). These are the template's
formulas ``cap`` and ``volt``, evaluated on whole columns of states with the same
integer comparisons, so that every state lands on the level the model gives it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from veribattery._types import IntArray
from veribattery.config import ModelParameters

__all__ = ["LEVEL_NAMES", "capacities", "level_bands", "voltage_levels"]

#: Voltage levels by number, as the model numbers them.
LEVEL_NAMES = ("low", "medium", "high")


def capacities(params: ModelParameters, rc: ArrayLike) -> IntArray:
    """``cap(rc) = floor(C_NEW x (1 - fade x rc))``, exactly, for each recharge count."""
    fade = params.fade
    counts = np.asarray(rc, dtype=np.int64)
    return (params.c_new * (fade.den - fade.num * counts)) // fade.den


def voltage_levels(params: ModelParameters, b: ArrayLike, rc: ArrayLike) -> IntArray:
    """The voltage level (0 low, 1 medium, 2 high) at charge *b* after *rc* recharges."""
    charge = np.asarray(b, dtype=np.int64)
    if params.fixed_level is not None:
        return np.full(charge.shape, params.fixed_level, dtype=np.int64)
    cap = capacities(params, rc)
    high, low = params.v_high, params.v_low
    return np.where(high.den * charge > high.num * cap, 2,
                    np.where(low.den * charge < low.num * cap, 0, 1)).astype(np.int64)


def level_bands(params: ModelParameters, level: ArrayLike,
                rc: ArrayLike) -> tuple[IntArray, IntArray]:
    """The least and greatest charge (0..cap) at which the voltage is at *level* after
    *rc* recharges; an empty band has least > greatest."""
    cap = capacities(params, rc)
    lvl = np.asarray(level, dtype=np.int64)
    if params.fixed_level is not None:
        empty = lvl != params.fixed_level
        return np.where(empty, cap + 1, 0), cap
    high, low = params.v_high, params.v_low
    # low: low.den*b < low.num*cap; high: high.den*b > high.num*cap (positive denominators).
    low_top = (low.num * cap - 1) // low.den
    high_bottom = (high.num * cap) // high.den + 1
    least = np.select([lvl == 0, lvl == 1], [np.zeros_like(cap), low_top + 1], high_bottom)
    greatest = np.select([lvl == 0, lvl == 1], [low_top, high_bottom - 1], cap)
    return least, np.minimum(greatest, cap)
