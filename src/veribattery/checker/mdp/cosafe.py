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

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.mdp.graph import ChoiceGraph, all_successors_in
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.rewards import reach_reward
from veribattery.checker.mdp.system import Objective

__all__ = ["next_reward", "trapped", "trapped_entries", "until_reward"]


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
    return trapped_entries(mdp, traps)[0]


def trapped_entries(mdp: MDP, traps: BoolArray) -> tuple[MDP, IntArray, IntArray]:
    """:func:`trapped`, and where the entries of the kept choices went: their positions
    in *mdp*'s transitions and in the trapped MDP's (a kept choice keeps its entries in
    their order, so the exact engine carries their rationals over; a trapped choice has
    one entry, its self-loop, probability 1)."""
    caught = traps[mdp.choice_owner]
    old = sp.csr_matrix(mdp.transitions)
    lengths = np.diff(old.indptr)
    indptr = np.zeros(mdp.num_choices + 1, dtype=np.int64)
    np.cumsum(np.where(caught, 1, lengths), out=indptr[1:])
    kept = np.flatnonzero(np.repeat(~caught, lengths))  # (old positions)
    owner = np.repeat(np.arange(mdp.num_choices), lengths)[kept]
    at = indptr[owner] + (kept - old.indptr[owner])
    indices = np.empty(int(indptr[-1]), dtype=old.indices.dtype)
    data = np.ones(int(indptr[-1]))
    indices[at], data[at] = old.indices[kept], old.data[kept]
    indices[indptr[:-1][caught]] = mdp.choice_owner[caught]
    transitions = sp.csr_matrix((data, indices, indptr), shape=old.shape)
    return MDP(transitions, mdp.row_groups, mdp.initial, labels=mdp.labels,
               choice_actions=mdp.choice_actions, actions=mdp.actions, rewards=mdp.rewards,
               states=mdp.states, variable_names=mdp.variable_names,
               deadlocks=mdp.deadlocks), kept, at
