"""Pmin and Pmax of ``remain U target`` (and ``F target``), unbounded, certified.

The pre-pass fixes the states of value 0 and 1 by graph search (:mod:`graph`).
For Pmax the end components among the remaining states are collapsed, so that
the Bellman operator of what is left has a unique fixed point (a strategy that
stays in an end component forever would otherwise make ``x = 1`` there a fixed
point too); for Pmin no end component is left among them (one would give
probability 0). The values are then approximated by policy iteration and
certified (:mod:`certificate`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.checker.bounds import Bounds
from veribattery.checker.mdp import graph as qualitative
from veribattery.checker.mdp.components import EndComponents, end_components
from veribattery.checker.mdp.graph import ChoiceGraph, all_successors_in
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.optimum import optimise, spread
from veribattery.checker.mdp.result import MdpResult
from veribattery.checker.mdp.strategy import Strategy, first_choice_where, lifted
from veribattery.checker.mdp.system import Objective, quotient_classes

__all__ = ["ReachPartition", "reach_partition", "reach_probability"]


def reach_probability(mdp: MDP, target: BoolArray, *, objective: Objective,
                      remain: BoolArray | None = None) -> MdpResult:
    """Minimal or maximal probability of ``remain U target`` (``F target`` without
    *remain*) in every state, with certified bounds and an optimal strategy.

    :param mdp: the model.
    :param target: states to reach.
    :param objective: ``"min"`` (Pmin) or ``"max"`` (Pmax).
    :param remain: states that may be passed through before *target* (None: all).
    :return: probabilities, their enclosures, and a memoryless deterministic strategy
        attaining them (for Pmax: one that also makes progress inside end components).
    """
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    remain = np.ones(mdp.num_states, dtype=bool) if remain is None else remain
    part = reach_partition(mdp, graph, remain, target, objective)
    values = Bounds.exact(part.yes.astype(np.float64))
    strategy = part.strategy
    if part.maybe.any():
        values, strategy = _quantitative(mdp, graph, part, objective, values, strategy)
    return MdpResult(values, Strategy(strategy))


@dataclass(frozen=True, slots=True)
class ReachPartition:
    """The states of value 0 (*no*), 1 (*yes*) and the others (:attr:`maybe`).

    :param strategy: per state, a choice that attains the value 1 on *yes* (Pmax) or
        0 on *no* (Pmin); the state's first choice elsewhere.
    """

    no: BoolArray
    yes: BoolArray
    strategy: IntArray

    @property
    def maybe(self) -> BoolArray:
        """The states whose value lies strictly between 0 and 1."""
        return ~(self.no | self.yes)


def reach_partition(mdp: MDP, graph: ChoiceGraph, remain: BoolArray, target: BoolArray,
                    objective: Objective) -> ReachPartition:
    """The qualitative pre-pass of Pmin or Pmax (``remain U target``).

    For Pmax the states of value 1 follow the witnesses of :func:`almost_surely`; for
    Pmin the states of value 0 in ``remain & !target`` keep to choices that never leave
    them (there is one: they are the complement of a universal attractor).
    """
    choices = mdp.row_groups[:-1].copy()
    moving = remain & ~target
    if objective == "max":
        yes, via = qualitative.almost_surely(graph, remain, target)
        choices[moving & yes] = via[moving & yes]
        return ReachPartition(qualitative.prob0a(graph, remain, target), yes, choices)
    no = qualitative.prob0e(graph, remain, target)
    avoiding = first_choice_where(mdp, all_successors_in(graph, no))
    choices[moving & no] = avoiding[moving & no]
    return ReachPartition(no, qualitative.prob1a(graph, remain, target, no), choices)


def _quantitative(mdp: MDP, graph: ChoiceGraph, part: ReachPartition, objective: Objective,
                  values: Bounds, strategy: IntArray) -> tuple[Bounds, IntArray]:
    """Values and strategy of the maybe states, merged into the qualitative ones."""
    components = _collapsed(graph, part.maybe) if objective == "max" else None
    class_of = quotient_classes(part.maybe, None if components is None else components.component)
    known = part.yes.astype(np.float64)
    found = optimise(mdp, class_of, known, objective, goal=part.yes, ceiling=1.0)
    return (spread(values, class_of, found.bounds),
            lifted(mdp, graph, found.system, found.rows, components, strategy))


def _collapsed(graph: ChoiceGraph, maybe: BoolArray) -> EndComponents:
    """The maximal end components among the *maybe* states."""
    return end_components(graph, maybe, all_successors_in(graph, maybe))
