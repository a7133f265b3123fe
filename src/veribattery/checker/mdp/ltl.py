"""LTL on an MDP: ``Pmax``/``Pmin`` of an LTL path formula, co-safe ``Rmin``/``Rmax``.

In the product of the MDP with the formula's parity automaton
(:mod:`veribattery.checker.ltl`), strategies are the model's (the automaton being
deterministic) and the formula holds on exactly the accepted paths: ``Pmax`` is the
maximal probability of reaching the product's accepting end components, certified by the
MDP solver as any ``F``. ``Pmin [ phi ] = 1 - Pmax [ !phi ]``, the negation read by the
complemented automaton on the same product. A co-safe reward runs until the automaton
reaches a state that accepts every continuation.
"""

from __future__ import annotations

import numpy as np

from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.ltl.acceptance import accepting_states
from veribattery.checker.ltl.automaton import StateSet, cosafe_of, parity_of
from veribattery.checker.ltl.product import Product, product
from veribattery.checker.mdp.graph import ChoiceGraph
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.rewards import reach_reward
from veribattery.checker.mdp.system import Objective
from veribattery.lang.nodes import CosafeReach, LtlPath

__all__ = ["accepted_probability", "cosafe_reward"]


def accepted_probability(mdp: MDP, path: LtlPath, states: StateSet, *, negated: bool,
                         progress: Progress | None = None) -> Bounds:
    """Per state, ``Pmax`` of *path* (of its negation if *negated*), certified."""
    automaton, column = parity_of(path.formula, states, mdp.num_states, path.span)
    if negated:
        automaton = automaton.complement()
    joint = product(mdp.transitions, mdp.row_groups, automaton, column)
    owner = np.repeat(np.arange(joint.num_states, dtype=np.int64), np.diff(joint.row_groups))
    target = accepting_states(ChoiceGraph.of(joint.transitions, owner),
                              automaton.priority[joint.automaton_state])
    found = reach_probability(_product_mdp(mdp, joint), target, objective="max",
                              progress=progress).bounds
    return joint.at_starts(found)


def cosafe_reward(mdp: MDP, rewards: np.ndarray, path: CosafeReach, states: StateSet, *,
                  objective: Objective, progress: Progress | None = None) -> Bounds:
    """Per state, ``Rmin``/``Rmax`` of the reward per choice *rewards* until the co-safe
    *path* is satisfied (infinite where a strategy of that objective leaves it unsure)."""
    automaton, column = cosafe_of(path.formula, states, mdp.num_states, path.span)
    joint = product(mdp.transitions, mdp.row_groups, automaton, column)
    done = automaton.accepting[joint.automaton_state]
    found = reach_reward(_product_mdp(mdp, joint), rewards[joint.choices], done,
                         objective=objective, progress=progress).bounds
    return joint.at_starts(found)


def _product_mdp(mdp: MDP, joint: Product) -> MDP:
    return MDP(joint.transitions, joint.row_groups, joint.start[mdp.initial])

