"""LTL on an MDP: ``Pmax``/``Pmin`` of an LTL path formula, co-safe ``Rmin``/``Rmax``.

In the product of the MDP with the formula's parity automaton
(:mod:`veribattery.checker.ltl`), strategies are the model's (the automaton being
deterministic) and the formula holds on exactly the accepted paths: ``Pmax`` is the
maximal probability of reaching the product's accepting end components, certified by the
MDP solver as any ``F``. ``Pmin [ phi ] = 1 - Pmax [ !phi ]``, the negation read by the
complemented automaton on the same product. A co-safe reward runs until the good-prefix
automaton has read a good prefix (:mod:`veribattery.checker.automata.cosafe`).
"""

from __future__ import annotations

import numpy as np

from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.ltl.automaton import StateSet
from veribattery.checker.ltl.product import Product
from veribattery.checker.ltl.targets import accepting_product, good_prefix_product
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.rewards import reach_reward
from veribattery.checker.mdp.system import Objective
from veribattery.lang.nodes import CosafeReach, LtlPath

__all__ = ["accepted_probability", "cosafe_reward", "product_mdp"]


def accepted_probability(mdp: MDP, path: LtlPath, states: StateSet, *, negated: bool,
                         progress: Progress | None = None) -> Bounds:
    """Per state, ``Pmax`` of *path* (of its negation if *negated*), certified."""
    joint, target = accepting_product(mdp.transitions, mdp.row_groups, path, states,
                                      negated=negated)
    found = reach_probability(product_mdp(mdp, joint), target, objective="max",
                              progress=progress).bounds
    return joint.at_starts(found)


def cosafe_reward(mdp: MDP, rewards: np.ndarray, path: CosafeReach, states: StateSet, *,
                  objective: Objective, progress: Progress | None = None) -> Bounds:
    """Per state, ``Rmin``/``Rmax`` of the reward per choice *rewards* until the co-safe
    *path* is satisfied (infinite where a strategy of that objective leaves it unsure)."""
    joint, done = good_prefix_product(mdp.transitions, mdp.row_groups, path, states)
    found = reach_reward(product_mdp(mdp, joint), rewards[joint.choices], done,
                         objective=objective, progress=progress).bounds
    return joint.at_starts(found)


def product_mdp(mdp: MDP, joint: Product) -> MDP:
    """The product as an MDP (no labels or rewards), started where *mdp* starts."""
    return MDP(joint.transitions, joint.row_groups, joint.start[mdp.initial])

