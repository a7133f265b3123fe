"""Each LTL question as a reachability question on a product: the product and its target.

The DTMC and MDP checkers, in floats and in rationals, all ask one of two things of a
model (*transitions*, choices x states, grouped by *row_groups*; a DTMC's rows are its
states): where the formula's parity automaton accepts, or where its good-prefix automaton
has read a good prefix. Here is that product and that set, built once for all four.
"""

from __future__ import annotations

import numpy as np

from veribattery._types import BoolArray, CsrMatrix, IntArray
from veribattery.checker.ltl.acceptance import accepting_states
from veribattery.checker.ltl.automaton import StateSet, cosafe_of, parity_of
from veribattery.checker.ltl.product import Product, product
from veribattery.checker.mdp.graph import ChoiceGraph
from veribattery.lang.nodes import CosafeReach, LtlPath

__all__ = ["accepting_product", "chain_groups", "good_prefix_product", "parity_product"]


def chain_groups(num_states: int) -> IntArray:
    """The row groups of a chain: one row per state."""
    return np.arange(num_states + 1, dtype=np.int64)


def parity_product(transitions: CsrMatrix, row_groups: IntArray, path: LtlPath,
                   states: StateSet, *, negated: bool = False) -> tuple[Product, IntArray]:
    """The product with *path*'s parity automaton (its complement if *negated*) and the
    priority of each product state."""
    automaton, column = parity_of(path.formula, states, int(row_groups.size - 1), path.span)
    if negated:
        automaton = automaton.complement()
    joint = product(transitions, row_groups, automaton, column)
    return joint, np.asarray(automaton.priority[joint.automaton_state], dtype=np.int64)


def accepting_product(transitions: CsrMatrix, row_groups: IntArray, path: LtlPath,
                      states: StateSet, *, negated: bool = False) -> tuple[Product, BoolArray]:
    """The product with *path*'s parity automaton (its complement if *negated*) and the
    states of its accepting end components."""
    joint, priority = parity_product(transitions, row_groups, path, states, negated=negated)
    owner = np.repeat(np.arange(joint.num_states, dtype=np.int64), np.diff(joint.row_groups))
    return joint, accepting_states(ChoiceGraph.of(joint.transitions, owner), priority)


def good_prefix_product(transitions: CsrMatrix, row_groups: IntArray, path: CosafeReach,
                        states: StateSet) -> tuple[Product, BoolArray]:
    """The product with the co-safe *path*'s good-prefix automaton and the states where a
    good prefix has been read."""
    automaton, column = cosafe_of(path.formula, states, int(row_groups.size - 1), path.span)
    joint = product(transitions, row_groups, automaton, column)
    return joint, np.asarray(automaton.accepting[joint.automaton_state], dtype=bool)
