"""LTL on a DTMC: ``P=? [ G F a ]``, ``A``/``E`` over LTL, co-safe ``R=? [ F (X a) ]``.

Each reduces to reaching a set of states in the product of the chain with an automaton
of the formula (:mod:`veribattery.checker.ltl`): a probability to reaching the accepting
bottom components of the product with its parity automaton, certified by the chain
solver as any ``F``; a reward to reaching a good prefix, in the product with its
good-prefix automaton (:mod:`veribattery.checker.automata.cosafe`); ``E`` to reaching a
cycle of even least priority.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from veribattery._types import BoolArray, CsrMatrix, FloatArray
from veribattery.checker import kernels
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.ltl.acceptance import good_cycle_reachers
from veribattery.checker.ltl.automaton import StateSet
from veribattery.checker.ltl.targets import (
    accepting_product,
    chain_groups,
    good_prefix_product,
    parity_product,
)
from veribattery.lang.nodes import CosafeReach, LtlPath

if TYPE_CHECKING:
    from veribattery.checker.workspace import Workspace

__all__ = ["cosafe_rewards", "ltl_probs", "ltl_quantified"]


def ltl_probs(P: CsrMatrix, path: LtlPath, states: StateSet, *, workspace: Workspace) -> Bounds:
    """Per state, the probability of the LTL path formula *path*, certified."""
    joint, target = accepting_product(P, chain_groups(P.shape[0]), path, states)
    found = kernels.until_probs(joint.transitions, np.ones(joint.num_states, dtype=bool),
                                target, workspace=workspace)
    return joint.at_starts(found)


def cosafe_rewards(P: CsrMatrix, rewards: FloatArray, path: CosafeReach, states: StateSet,
                   *, workspace: Workspace) -> Bounds:
    """Per state, the expected reward (per step, *rewards*) until the co-safe *path* is
    satisfied: infinite where that is not almost sure."""
    joint, done = good_prefix_product(P, chain_groups(P.shape[0]), path, states)
    found = kernels.reach_rewards(joint.transitions, rewards[joint.model_state], done,
                                  workspace=workspace)
    return joint.at_starts(found)


def ltl_quantified(edges: CsrMatrix, quantifier: str, path: LtlPath,
                   states: StateSet) -> BoolArray:
    """``E [ path ]`` (some path of the graph *edges* satisfies it) or ``A [ path ]`` (every
    path does: no path satisfies its negation)."""
    joint, priority = parity_product(edges, chain_groups(edges.shape[0]), path, states,
                                     negated=quantifier == "A")
    found = good_cycle_reachers(joint.transitions, priority)[joint.start]
    return np.asarray(~found if quantifier == "A" else found, dtype=bool)
