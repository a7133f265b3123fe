"""LTL on an MDP in rationals: the products of :mod:`.ltl` with the model's rationals.

The product copies the model's entries, so its exact probabilities are the model's read
through :attr:`Product.entries`; its reachability optimum is then solved as any
``Pmax [ F ]`` or ``Rmin``/``Rmax [ F ]`` in rationals.
"""

from __future__ import annotations

import numpy as np

from veribattery.checker.ltl.automaton import StateSet
from veribattery.checker.ltl.product import Product
from veribattery.checker.ltl.targets import accepting_product, good_prefix_product
from veribattery.checker.mdp.exact import exact_reach_reward
from veribattery.checker.mdp.exact_steps import exact_until
from veribattery.checker.mdp.ltl import product_mdp
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.rational import ObjectArray
from veribattery.checker.mdp.system import Objective
from veribattery.lang.nodes import CosafeReach, LtlPath

__all__ = ["exact_accepted_probability", "exact_cosafe_reward"]


def exact_accepted_probability(mdp: MDP, probabilities: ObjectArray, path: LtlPath,
                               states: StateSet, *, negated: bool) -> ObjectArray:
    """Per state, the exact ``Pmax`` of *path* (of its negation if *negated*)."""
    joint, target = accepting_product(mdp.transitions, mdp.row_groups, path, states,
                                      negated=negated)
    found = exact_until(product_mdp(mdp, joint), _copied(probabilities, joint), None,
                        target, None, "max")
    return np.asarray(found[joint.start], dtype=object)


def exact_cosafe_reward(mdp: MDP, probabilities: ObjectArray, rewards: ObjectArray,
                        path: CosafeReach, states: StateSet, *,
                        objective: Objective) -> tuple[ObjectArray, np.ndarray]:
    """Per state, the exact ``Rmin``/``Rmax`` of *rewards* (per choice) until the co-safe
    *path* holds: ``(values, infinite)``."""
    joint, done = good_prefix_product(mdp.transitions, mdp.row_groups, path, states)
    found = exact_reach_reward(product_mdp(mdp, joint),
                               np.asarray(rewards[joint.choices], dtype=object), done,
                               objective=objective, probabilities=_copied(probabilities, joint))
    return (np.asarray(found.values[joint.start], dtype=object),
            np.asarray(found.infinite[joint.start], dtype=bool))


def _copied(probabilities: ObjectArray, joint: Product) -> ObjectArray:
    """The model's rationals at the product's entries."""
    return np.asarray(probabilities[joint.entries], dtype=object)
