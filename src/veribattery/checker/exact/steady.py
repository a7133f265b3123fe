"""Long-run operators in exact arithmetic: ``S=? [phi]``, ``R=? [S]`` and ``R=? [C]``.

As on the float side (:mod:`~veribattery.checker.kernels.steady`): the bottom strongly
connected components (BSCCs) of the chain's graph; in each, the average of the weights
under its stationary distribution, by the renewal theorem from a reference state *r*,
``(w_r + sum_j P_rj h_j) / (1 + sum_j P_rj l_j)`` with *h* and *l* the expected weight
and number of steps until *r* (every state of an irreducible chain reaches *r* almost
surely, so both systems are nonsingular and the SCC-wise exact solve applies); then
each BSCC's average carried back to the transient states by one absorption system,
which every transient state leaves almost surely. Unique for an irreducible chain,
periodic or not, and equal to the Cesàro average PRISM reports.
"""

from __future__ import annotations

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.checker.exact.numeric import (
    _ONE,
    _ZERO,
    ExactValues,
    prepared_system,
    reach_rewards,
)
from veribattery.checker.exact.solve import row_products, solve
from veribattery.checker.kernels.steady import Bsccs, bsccs
from veribattery.checker.workspace import Workspace
from veribattery.explore.exact.dtmc import ExactDTMC
from veribattery.explore.exact.rational import ObjectArray

__all__ = ["long_run_values", "total_rewards"]


def long_run_values(model: ExactDTMC, workspace: Workspace, weights: ObjectArray) -> ObjectArray:
    """Per state, the exact long-run average of *weights* per step (``S=? [phi]``: the
    indicator of *phi*; ``R=? [S]``: the expected reward per step)."""
    P = model.dtmc.transitions
    parts = bsccs(P)
    values = np.full(P.shape[0], _ZERO, dtype=object)
    recurrent = parts.recurrent
    values[recurrent] = _bscc_averages(model, workspace, parts, weights)[
        parts.component[recurrent]]
    transient = ~recurrent
    if transient.any():
        rows = np.flatnonzero(transient)
        reached = row_products(P, model.probabilities, rows, values)  # (0 on the transient)
        values[rows] = solve(prepared_system(model, workspace, transient), reached)
    return values


def total_rewards(model: ExactDTMC, workspace: Workspace, rewards: ObjectArray) -> ExactValues:
    """Exact ``R=? [C]``: the reward until a BSCC without rewards is reached, infinite
    where that is not almost sure (a BSCC with a reward earns it infinitely often)."""
    parts = bsccs(model.dtmc.transitions)
    paying = np.zeros(parts.count, dtype=bool)
    recurrent = parts.recurrent
    paying[parts.component[recurrent & (rewards != _ZERO)]] = True
    cold = recurrent & ~paying[np.maximum(parts.component, 0)]
    return reach_rewards(model, workspace, rewards, cold)


def _bscc_averages(model: ExactDTMC, workspace: Workspace, parts: Bsccs,
                   weights: ObjectArray) -> ObjectArray:
    """The average of *weights* under each BSCC's stationary distribution (the weight
    itself where it is the same in every state of the BSCC: no solve)."""
    states = np.flatnonzero(parts.recurrent)
    comp = parts.component[states]
    order = np.argsort(comp, kind="stable")
    first = np.searchsorted(comp[order], np.arange(parts.count))
    refs = states[order[first]]  # per BSCC, its first state
    differs = np.asarray(weights[states] != weights[refs[comp]], dtype=bool)
    varying = np.bincount(comp[differs], minlength=parts.count) > 0
    averages = np.asarray(weights[refs], dtype=object).copy()
    if varying.any():
        averages[varying] = _renewal(model, workspace, parts, refs[varying], weights)
    return averages


def _renewal(model: ExactDTMC, workspace: Workspace, parts: Bsccs, refs: IntArray,
             weights: ObjectArray) -> ObjectArray:
    """``E[cycle weight] / E[cycle length]`` of the cycles from each state of *refs*
    back to it, within its BSCC."""
    P, probabilities = model.dtmc.transitions, model.probabilities
    inside: BoolArray = np.isin(parts.component, parts.component[refs]) & parts.recurrent
    inside[refs] = False
    gained = np.full(P.shape[0], _ZERO, dtype=object)
    steps = np.full(P.shape[0], _ZERO, dtype=object)
    if inside.any():
        rows = np.flatnonzero(inside)
        system = prepared_system(model, workspace, inside)
        gained[rows] = solve(system, weights[rows])
        steps[rows] = solve(system, np.full(rows.size, _ONE, dtype=object))
    cycle_weight = weights[refs] + row_products(P, probabilities, refs, gained)
    cycle_length = _ONE + row_products(P, probabilities, refs, steps)
    return np.asarray(cycle_weight / cycle_length, dtype=object)
