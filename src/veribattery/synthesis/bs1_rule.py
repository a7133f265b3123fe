"""BS1's return rule as a charge threshold, computed from the config alone.

BS1 goes on at a decision iff the charge predicted to be left after the intended
sequence stays at or above ``safe_t`` of the capacity (model-spec.md, "The drone's
decisions"): ``safe.den x (b - pred) >= safe.num x cap(rc)``, with ``pred`` from the
costs at the current wind and voltage level. Within one voltage level the costs are
fixed, so BS1 goes on exactly from ``pred + ceil(safe.num x cap / safe.den)`` upwards
(and never below the level's least charge). BS1 is a threshold over the whole charge
range too: a higher charge never lowers the level, and a higher level never costs more.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from veribattery._types import IntArray
from veribattery.config import ModelParameters
from veribattery.synthesis.levels import capacities, level_bands

__all__ = ["NO_CHARGE", "bs1_least_go_on", "bs1_least_go_on_at"]

#: Marks "no charge in the band": BS1 does not go on at this level at all.
NO_CHARGE = -1


def bs1_least_go_on(params: ModelParameters, decision: str, k: int, wsp: int, rc: int,
                    level: int) -> int | None:
    """The least charge at *level* at which BS1 goes on at *decision* (one of
    :data:`~veribattery.synthesis.decisions.DECISIONS`) in route cell *k*, wind *wsp*,
    after *rc* recharges; None if it returns at every charge of the level."""
    least = bs1_least_go_on_at(params, np.array([decision]), np.array([k]), np.array([wsp]),
                               np.array([rc]), np.array([level]))[0]
    return None if least == NO_CHARGE else int(least)


def bs1_least_go_on_at(params: ModelParameters, decision: ArrayLike, k: ArrayLike,
                       wsp: ArrayLike, rc: ArrayLike, level: ArrayLike) -> IntArray:
    """:func:`bs1_least_go_on` on columns; :data:`NO_CHARGE` where BS1 never goes on."""
    kinds = np.asarray(decision, dtype=object)
    cell, wind, count, lvl = (np.asarray(a, dtype=np.int64) for a in (k, wsp, rc, level))
    predicted = _predicted_use(params, kinds, cell, wind, lvl)
    safe = params.safe
    reserve = -((-safe.num * capacities(params, count)) // safe.den)  # ceil, exactly
    least, greatest = level_bands(params, lvl, count)
    first = np.maximum(least, predicted + reserve)
    return np.where(first <= greatest, first, NO_CHARGE)


def _predicted_use(params: ModelParameters, kinds: np.ndarray, k: IntArray, wsp: IntArray,
                   level: IntArray) -> IntArray:
    """``pred`` of the spec's ``ok_X`` for each decision, at its wind and level."""
    costs = params.costs
    tl, cell, ins = (np.asarray(table, dtype=np.int64)[wsp, level]
                     for table in (costs.takeoff_land, costs.cell, costs.inspection))
    layout = params.layout
    dist = np.asarray(layout.dist, dtype=np.int64)[np.clip(k, 0, layout.num_cells - 1)]
    step = np.append(np.asarray(layout.step, dtype=np.int64), 0)[
        np.clip(k, 0, layout.num_cells - 1)]
    return np.select([kinds == "takeoff", kinds == "fly", kinds == "inspect"],
                     [tl + dist * cell + ins, dist * cell + ins, ins], step * cell + ins)
