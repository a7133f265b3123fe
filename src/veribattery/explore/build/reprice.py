"""Re-pricing known branches under a layer plan (structure reuse, see ``reuse.structure``):
the branch kinds of a frontier, and their probabilities under another plan's factors,
multiplied as the fused expansion (:mod:`~veribattery.explore.build.fused`) does."""

from __future__ import annotations

import numpy as np

from veribattery._types import FloatArray, IntArray
from veribattery.explore.build.fused import (
    LayerPlan,
    _enabled,
    _positions,
    _probabilities,
    _sums_ok,
)

__all__ = ["branch_kinds", "reprice"]


def branch_kinds(plan: LayerPlan, states: IntArray) -> tuple[IntArray, IntArray]:
    """The branch kind and the *states*-local source of every branch out of *states*,
    in the builder's order, zero-probability branches included."""
    enabled, _ = _enabled(plan, states)
    src, kind = _positions(enabled)
    widths = plan.widths[kind]
    firsts = np.cumsum(widths) - widths
    branch = np.repeat(plan.starts[kind] - firsts, widths) + np.arange(int(widths.sum()))
    return branch, np.repeat(src, widths)


def reprice(plan: LayerPlan, states: IntArray, branch: IntArray,
            source: IntArray) -> FloatArray | None:
    """The probabilities (before the 1/n weighting) of the branches of kinds *branch*
    out of ``states[source]`` under *plan*'s factors, multiplied as
    :meth:`~veribattery.explore.build.fused.LayerPlan.expand` does; None if a factor is a
    risky expression (it would need the guards), a factor is negative or a choice's sum
    is off (the builder then decides).
    """
    if any(e.risky for e in plan.factors.exprs):
        return None
    present = list(range(plan.kinds + 1))
    none = np.empty((0, 0), dtype=bool)
    probability = _probabilities(plan.factors, states, none, present, (branch, source))
    if probability is None or plan.unchecked_sums.isdisjoint(present):
        return probability
    kind = np.repeat(np.arange(plan.widths.size), plan.widths)[branch]
    firsts = np.flatnonzero(branch == plan.starts[kind])
    return probability if _sums_ok(plan, present, probability, firsts, kind[firsts]) else None
