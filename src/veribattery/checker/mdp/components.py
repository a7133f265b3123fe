"""Maximal end components: sets of states a strategy can stay in forever, almost surely.

An end component is a set of states *C* with, per state, a nonempty set of its
choices whose successors all lie in *C*, such that the graph of those choices is
strongly connected. The maximal ones partition the states that lie in any end
component. The decomposition (de Alfaro 1997; Baier & Katoen 2008, Alg. 47) is
a fixpoint of two vectorised steps: drop the choices that can leave the states
still alive, then split the states by strongly connected components and drop the
choices that cross from one component to another.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._types import BoolArray, IntArray
from veribattery.checker.mdp.graph import ChoiceGraph, all_successors_in

__all__ = ["EndComponents", "end_components"]


@dataclass(frozen=True, slots=True)
class EndComponents:
    """The maximal end components of part of an MDP.

    :param component: per state, the index of its end component, or -1.
    :param inside: per choice, whether it belongs to its state's end component (it is
        allowed and all its successors lie in that component).
    :param count: the number of end components.
    """

    component: IntArray
    inside: BoolArray
    count: int

    @property
    def states(self) -> BoolArray:
        """The states that lie in some end component."""
        return np.asarray(self.component >= 0, dtype=bool)


def end_components(graph: ChoiceGraph, states: BoolArray,
                   choices: BoolArray | None = None) -> EndComponents:
    """The maximal end components within *states*, using only *choices*.

    :param states: the states the components may contain.
    :param choices: the choices they may use (None: all choices of those states).
    """
    alive_choices = states[graph.owner].copy()
    if choices is not None:
        alive_choices &= choices
    alive = states.copy()
    labels = np.full(graph.num_states, -1, dtype=np.int64)
    while True:
        alive_choices &= all_successors_in(graph, alive)
        alive &= _has_choice(graph, alive_choices)
        alive_choices &= alive[graph.owner]
        labels = _strong_components(graph, alive, alive_choices)
        crossing = _leaves_component(graph, labels)
        if not np.any(alive_choices & crossing):
            break
        alive_choices &= ~crossing
    return _numbered(labels, alive, alive_choices)


def _has_choice(graph: ChoiceGraph, choices: BoolArray) -> BoolArray:
    return np.bincount(graph.owner[choices], minlength=graph.num_states) > 0


def _strong_components(graph: ChoiceGraph, alive: BoolArray, choices: BoolArray) -> IntArray:
    """Strongly connected components of the graph of *choices* (-1 off *alive*)."""
    n = graph.num_states
    sizes = np.diff(graph.successor_ptr)
    used = np.repeat(choices, sizes)
    tails = np.repeat(graph.owner, sizes)[used]
    heads = graph.successors[used]
    edges = sp.csr_matrix((np.ones(tails.size, dtype=np.int8), (tails, heads)), shape=(n, n))
    _, labels = csgraph.connected_components(edges, directed=True, connection="strong")
    return np.where(alive, labels, -1).astype(np.int64)


def _leaves_component(graph: ChoiceGraph, labels: IntArray) -> BoolArray:
    """Per choice: whether some successor lies outside its owner's component."""
    sizes = np.diff(graph.successor_ptr)
    own = np.repeat(labels[graph.owner], sizes)
    differs = labels[graph.successors] != own
    return np.asarray(np.logical_or.reduceat(differs, graph.successor_ptr[:-1]), dtype=bool)


def _numbered(labels: IntArray, alive: BoolArray, inside: BoolArray) -> EndComponents:
    """Components renumbered 0..count-1 (in order of their smallest state)."""
    component = np.full(labels.size, -1, dtype=np.int64)
    if not alive.any():
        return EndComponents(component, inside, 0)
    _, first, dense = np.unique(labels[alive], return_index=True, return_inverse=True)
    rank = np.empty(first.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    component[alive] = rank[dense]
    return EndComponents(component, inside, int(first.size))
