"""Where the product accepts: its accepting end components, and its good cycles.

A path of the product is accepted when the least priority it visits infinitely often is
even. Almost every path of a Markov chain, and under any strategy of an MDP, ends in an
end component and visits all of it; a strategy can stay in an end component and visit
all its states. So the formula's probability is that of reaching the union of the
*accepting* end components -- those, for some even *p*, within the states of priority at
least *p* that contain one of priority *p* (Baier & Katoen 2008, Sec. 10.6.4, for Rabin
conditions, of which a parity condition is one). In a chain they are its bottom strongly
connected components whose least priority is even.

Over paths rather than probabilities (``E [ ... ]``), a path satisfies the formula when it
can reach a cycle whose least priority is even: the same search in the graph whose every
edge is a choice of its own.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from veribattery._types import BoolArray, CsrMatrix
from veribattery.checker.mdp.components import end_components
from veribattery.checker.mdp.graph import ChoiceGraph, can_reach

__all__ = ["accepting_states", "good_cycle_reachers"]


def accepting_states(graph: ChoiceGraph, priority: NDArray[np.integer[Any]]) -> BoolArray:
    """The states of the accepting end components of *graph* (states by *priority*)."""
    accepted = np.zeros(graph.num_states, dtype=bool)
    for p in np.unique(priority):
        if p % 2:
            continue
        found = end_components(graph, priority >= p)
        hits = np.unique(found.component[(priority == p) & (found.component >= 0)])
        if hits.size:
            accepted |= np.isin(found.component, hits)
    return accepted


def good_cycle_reachers(edges: CsrMatrix, priority: NDArray[np.integer[Any]]) -> BoolArray:
    """The states of the graph *edges* (states x states, positive entries) from which
    some path visits a cycle of even least priority."""
    pattern = sp.csr_matrix(edges, copy=True)
    pattern.data = (pattern.data > 0).astype(np.int8)
    pattern.eliminate_zeros()
    pattern.sum_duplicates()
    n = pattern.shape[0]
    owner = np.repeat(np.arange(n, dtype=np.int64), np.diff(pattern.indptr))
    one_per_edge = sp.csr_matrix(
        (np.ones(pattern.nnz), pattern.indices, np.arange(pattern.nnz + 1)),
        shape=(pattern.nnz, n))
    graph = ChoiceGraph.of(one_per_edge, owner)
    good = accepting_states(graph, priority)
    return can_reach(graph, np.ones(n, dtype=bool), good)
