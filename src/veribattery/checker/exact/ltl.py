"""LTL on a DTMC in rationals: ``P=? [ G F a ]`` and co-safe ``R=? [ F (X a) ]`` exactly.

The same products as in floating point (:mod:`veribattery.checker.formula.ltl`): the
product chain carries the model's rationals entry for entry, and its reachability
probability or reward is solved exactly (:mod:`veribattery.checker.exact.numeric`).
"""

from __future__ import annotations

import numpy as np

from veribattery.checker.exact.numeric import ExactValues, reach_rewards, until_probs
from veribattery.checker.ltl.automaton import StateSet
from veribattery.checker.ltl.product import Product
from veribattery.checker.ltl.targets import accepting_product, chain_groups, good_prefix_product
from veribattery.checker.workspace import Workspace
from veribattery.explore.dtmc import DTMC
from veribattery.explore.exact.dtmc import ExactDTMC
from veribattery.explore.exact.rational import ObjectArray
from veribattery.lang.nodes import CosafeReach, LtlPath

__all__ = ["exact_cosafe_rewards", "exact_ltl_probs"]


def exact_ltl_probs(model: ExactDTMC, workspace: Workspace, path: LtlPath,
                    states: StateSet) -> ObjectArray:
    """Per state, the exact probability of the LTL path formula *path*."""
    P = model.dtmc.transitions
    joint, target = accepting_product(P, chain_groups(P.shape[0]), path, states)
    everywhere = np.ones(joint.num_states, dtype=bool)
    found = until_probs(_chain(model, joint), workspace, everywhere, target)
    return np.asarray(found[joint.start], dtype=object)


def exact_cosafe_rewards(model: ExactDTMC, workspace: Workspace, rewards: ObjectArray,
                         path: CosafeReach, states: StateSet) -> ExactValues:
    """Per state, the exact reward (per step, *rewards*) until the co-safe *path* holds."""
    P = model.dtmc.transitions
    joint, done = good_prefix_product(P, chain_groups(P.shape[0]), path, states)
    found = reach_rewards(_chain(model, joint), workspace,
                          np.asarray(rewards[joint.model_state], dtype=object), done)
    return ExactValues(found.values[joint.start], found.infinite[joint.start])


def _chain(model: ExactDTMC, joint: Product) -> ExactDTMC:
    """The product as a chain with the model's rationals (no labels, rewards, states)."""
    size = joint.num_states
    dtmc = DTMC(joint.transitions, np.zeros((size, 0), dtype=np.int64), (),
                np.asarray(joint.start, dtype=np.int64), {}, ())
    return ExactDTMC(dtmc, np.asarray(model.probabilities[joint.entries], dtype=object), (),
                     model.constants)
