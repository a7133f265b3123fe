"""LTL on an MDP in rationals: the products of :mod:`.ltl` with the model's rationals.

The product copies the model's entries, so its exact probabilities are the model's read
through :attr:`Product.entries`; its reachability optimum is then solved as any
``Pmax [ F ]`` or ``Rmin``/``Rmax [ F ]`` in rationals.
"""

from __future__ import annotations

import numpy as np

from veribattery.checker.ltl.acceptance import accepting_states
from veribattery.checker.ltl.automaton import StateSet, cosafe_of, parity_of
from veribattery.checker.ltl.product import product
from veribattery.checker.mdp.exact import exact_reach_reward
from veribattery.checker.mdp.exact_steps import exact_until
from veribattery.checker.mdp.graph import ChoiceGraph
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.rational import ObjectArray
from veribattery.checker.mdp.system import Objective
from veribattery.lang.nodes import CosafeReach, LtlPath

__all__ = ["exact_accepted_probability", "exact_cosafe_reward"]


def exact_accepted_probability(mdp: MDP, probabilities: ObjectArray, path: LtlPath,
                               states: StateSet, *, negated: bool) -> ObjectArray:
    """Per state, the exact ``Pmax`` of *path* (of its negation if *negated*)."""
    automaton, column = parity_of(path.formula, states, mdp.num_states, path.span)
    if negated:
        automaton = automaton.complement()
    joint = product(mdp.transitions, mdp.row_groups, automaton, column)
    owner = np.repeat(np.arange(joint.num_states, dtype=np.int64), np.diff(joint.row_groups))
    target = accepting_states(ChoiceGraph.of(joint.transitions, owner),
                              automaton.priority[joint.automaton_state])
    found = exact_until(MDP(joint.transitions, joint.row_groups, joint.start[mdp.initial]),
                        np.asarray(probabilities[joint.entries], dtype=object), None, target,
                        None, "max")
    return np.asarray(found[joint.start], dtype=object)


def exact_cosafe_reward(mdp: MDP, probabilities: ObjectArray, rewards: ObjectArray,
                        path: CosafeReach, states: StateSet, *,
                        objective: Objective) -> tuple[ObjectArray, np.ndarray]:
    """Per state, the exact ``Rmin``/``Rmax`` of *rewards* (per choice) until the co-safe
    *path* holds: ``(values, infinite)``."""
    automaton, column = cosafe_of(path.formula, states, mdp.num_states, path.span)
    joint = product(mdp.transitions, mdp.row_groups, automaton, column)
    done = automaton.accepting[joint.automaton_state]
    found = exact_reach_reward(
        MDP(joint.transitions, joint.row_groups, joint.start[mdp.initial]),
        np.asarray(rewards[joint.choices], dtype=object), done, objective=objective,
        probabilities=np.asarray(probabilities[joint.entries], dtype=object))
    return (np.asarray(found.values[joint.start], dtype=object),
            np.asarray(found.infinite[joint.start], dtype=bool))
