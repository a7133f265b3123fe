"""Pmin and Pmax of ``remain U target`` (and ``F target``), unbounded, certified.

The pre-pass fixes the states of value 0 and 1 by graph search (:mod:`graph`).
For Pmax the end components among the remaining states are collapsed, so that
the Bellman operator of what is left has a unique fixed point (a strategy that
stays in an end component forever would otherwise make ``x = 1`` there a fixed
point too); for Pmin no end component is left among them (one would give
probability 0). The values are then approximated by policy iteration and
certified (:mod:`optimum`).
"""

from __future__ import annotations

import numpy as np

from veribattery._types import BoolArray
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.mdp import graph as qualitative
from veribattery.checker.mdp.components import end_components
from veribattery.checker.mdp.graph import ChoiceGraph, all_successors_in
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.optimum import Problem, solve
from veribattery.checker.mdp.result import MdpResult
from veribattery.checker.mdp.strategy import first_choice_where
from veribattery.checker.mdp.system import Objective

__all__ = ["reach_probability", "reach_problem"]


def reach_probability(mdp: MDP, target: BoolArray, *, objective: Objective,
                      remain: BoolArray | None = None,
                      progress: Progress | None = None) -> MdpResult:
    """Minimal or maximal probability of ``remain U target`` (``F target`` without
    *remain*) in every state, with certified bounds and an optimal strategy.

    :param mdp: the model.
    :param target: states to reach.
    :param objective: ``"min"`` (Pmin) or ``"max"`` (Pmax).
    :param remain: states that may be passed through before *target* (None: all).
    :param progress: told how far the solve is (:func:`~veribattery.checker.mdp.optimum.solve`).
    :return: probabilities, their enclosures, and a memoryless deterministic strategy
        attaining them (for Pmax: one that also makes progress inside end components).
    """
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    return solve(mdp, graph, reach_problem(mdp, graph, target, objective, remain), None,
                 progress=progress)


def reach_problem(mdp: MDP, graph: ChoiceGraph, target: BoolArray, objective: Objective,
                  remain: BoolArray | None = None) -> Problem:
    """The qualitative pre-pass of Pmin or Pmax (``remain U target``).

    For Pmax the states of value 1 follow the witnesses of
    :func:`~veribattery.checker.mdp.graph.almost_surely`; for Pmin the states of value
    0 in ``remain & !target`` keep to choices that never leave them (there is one:
    they are the complement of a universal attractor).
    """
    remain = np.ones(mdp.num_states, dtype=bool) if remain is None else remain
    choices = mdp.row_groups[:-1].copy()
    moving = remain & ~target
    if objective == "max":
        yes, via = qualitative.almost_surely(graph, remain, target)
        no = qualitative.prob0a(graph, remain, target)
        choices[moving & yes] = via[moving & yes]
    else:
        no = qualitative.prob0e(graph, remain, target)
        yes = qualitative.prob1a(graph, remain, target, no)
        avoiding = first_choice_where(mdp, all_successors_in(graph, no))
        choices[moving & no] = avoiding[moving & no]
    maybe = ~(no | yes)
    components = None
    if objective == "max":
        components = end_components(graph, maybe, all_successors_in(graph, maybe))
    return Problem(objective, maybe, yes.astype(np.float64), choices, yes, components)
