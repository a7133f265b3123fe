"""Co-safe reward paths on an MDP: ``R [ a U b ]`` and ``R [ X b ]``.

PRISM reads a reward path that is not ``F``, ``C`` or ``I`` as co-safe LTL: the
reward is accumulated until the path formula is satisfied, and a run that can no
longer satisfy it collects infinitely much. For ``a U b`` the run fails exactly
when it enters a state with neither *a* nor *b* before *b*: those states become
traps (a self-loop for each of their choices), and the value is ``R [ F b ]`` on
the trapped MDP -- infinite from a trap, since *b* is never reached from there.
For ``X b`` it is the reward of the first step if that step surely lands in *b*.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, FloatArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.mdp.graph import ChoiceGraph, all_successors_in
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.rewards import reach_reward
from veribattery.checker.mdp.system import Objective

__all__ = ["next_reward", "until_reward"]


def until_reward(mdp: MDP, rewards: FloatArray, remain: BoolArray, target: BoolArray, *,
                 objective: Objective) -> Bounds:
    """Rmin or Rmax of ``remain U target``: reward per choice until *target*, infinite
    for a run that leaves *remain* first.

    :param rewards: per choice, the reward of one step taken with it (nonnegative).
    """
    return reach_reward(trapped(mdp, ~remain & ~target), rewards, target,
                        objective=objective).bounds


def next_reward(mdp: MDP, rewards: FloatArray, target: BoolArray, *,
                objective: Objective) -> Bounds:
    """Rmin or Rmax of ``X target``: the first step's reward if it surely lands in
    *target*, else infinite (so Rmin takes the cheapest sure choice, and Rmax is
    infinite where some choice can miss)."""
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    per_choice = np.where(all_successors_in(graph, target), rewards, np.inf)
    starts = mdp.row_groups[:-1]
    reduce = np.minimum if objective == "min" else np.maximum
    return Bounds.exact(np.asarray(reduce.reduceat(per_choice, starts), dtype=np.float64))


def trapped(mdp: MDP, traps: BoolArray) -> MDP:
    """*mdp* with every choice of a state in *traps* turned into a self-loop."""
    caught = traps[mdp.choice_owner]
    rows = sp.csr_matrix(mdp.transitions)
    loops = sp.csr_matrix((np.ones(mdp.num_choices), (np.arange(mdp.num_choices),
                                                      mdp.choice_owner)), shape=rows.shape)
    keep = sp.diags((~caught).astype(np.float64))
    transitions = sp.csr_matrix(keep @ rows + sp.diags(caught.astype(np.float64)) @ loops)
    transitions.eliminate_zeros()
    return MDP(transitions, mdp.row_groups, mdp.initial, labels=mdp.labels,
               choice_actions=mdp.choice_actions, actions=mdp.actions, rewards=mdp.rewards,
               states=mdp.states, variable_names=mdp.variable_names,
               deadlocks=mdp.deadlocks)
