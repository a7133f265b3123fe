"""The product of a model with a deterministic automaton, reachable part only.

A product state is a pair ``(s, q)``: the model in *s*, the automaton in *q* after
reading the letters of the states so far, *s*'s included. A choice of *s* leads from
``(s, q)`` to ``(t, successor[q, letter(t)])`` with the choice's probability of *t*, so
the product has exactly the model's choices, one copy per automaton state it meets. A
path of the model from *s* corresponds to one path of the product from
``(s, successor[initial, letter(s)])``, its *start*; the automaton being deterministic,
strategies correspond too, and a formula's probability (its optimum) from *s* is the
product's acceptance probability (optimum) from the start of *s*.

Built without a loop over states: the product's state graph over all pairs is the model's
state graph copied once per automaton state (the successor table picks each copy's
columns); a breadth-first search in C from every start keeps the reachable pairs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse import csgraph

from veribattery._types import CsrMatrix, IntArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.mdp.graph import segments

__all__ = ["Automaton", "Product", "product"]


class Automaton(Protocol):
    """A complete deterministic automaton: ``successor[q, column]`` from *initial*."""

    @property
    def initial(self) -> int: ...

    @property
    def successor(self) -> NDArray[np.integer[Any]]: ...


@dataclass(frozen=True, slots=True)
class Product:
    """The reachable product of a model (choices x states) and an automaton.

    :param transitions: product choices x product states; the choices of a product state
        are its model state's, in their order.
    :param row_groups: per product state, the offsets of its choices.
    :param choices: per product choice, the model choice it copies.
    :param entries: per stored entry of *transitions*, the entry of the model's it copies
        (where exact probabilities are read).
    :param model_state: per product state, its model state.
    :param automaton_state: per product state, its automaton state.
    :param start: per model state, the product state a path from it starts in.
    """

    transitions: CsrMatrix
    row_groups: IntArray
    choices: IntArray
    entries: IntArray
    model_state: IntArray
    automaton_state: IntArray
    start: IntArray

    @property
    def num_states(self) -> int:
        """Number of product states."""
        return int(self.model_state.size)

    def at_starts(self, found: Bounds) -> Bounds:
        """Per model state, the product's *found* values at its start."""
        start = self.start
        return Bounds(found.value[start], found.lower[start], found.upper[start])


def product(transitions: CsrMatrix, row_groups: IntArray, automaton: Automaton,
            column: IntArray) -> Product:
    """The product of the model (*transitions*, choices x states, grouped by *row_groups*)
    with the deterministic *automaton*, each state reading its *column* of the automaton's
    table (its letter), from every model state.

    Pairs are numbered automaton-state-major (``q * n + s``) while they are searched.
    """
    n = int(row_groups.size - 1)
    owner = np.repeat(np.arange(n, dtype=np.int64), np.diff(row_groups))
    after = np.asarray(automaton.successor[:, column], dtype=np.int64)  # (q, t) -> q'
    starts = after[automaton.initial] * n + np.arange(n, dtype=np.int64)
    reached = _reachable(_state_graph(transitions, owner, n), after, starts)
    number = np.full(after.shape[0] * n, -1, dtype=np.int64)
    number[reached] = np.arange(reached.size, dtype=np.int64)
    model_state, automaton_state = reached % n, reached // n
    sizes = np.diff(row_groups)[model_state]
    groups = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    copied = segments(np.asarray(row_groups, dtype=np.int64), model_state)
    rows = transitions[copied]
    state_of_entry = np.repeat(automaton_state, sizes)
    q_of_entry = np.repeat(state_of_entry, np.diff(rows.indptr))
    columns = number[after[q_of_entry, rows.indices] * n + rows.indices]
    # Columns ascending in each row (the kernels' canonical form, so that none sorts the
    # rows in place and moves the entries away from *entries*)
    row_of_entry = np.repeat(np.arange(copied.size), np.diff(rows.indptr))
    order = np.lexsort((columns, row_of_entry))
    entries = segments(np.asarray(transitions.indptr, dtype=np.int64), copied)[order]
    matrix = sp.csr_matrix((rows.data[order], columns[order], rows.indptr),
                           shape=(copied.size, reached.size))
    return Product(matrix, groups, copied, entries, model_state, automaton_state,
                   number[starts])


def _state_graph(transitions: CsrMatrix, owner: IntArray, n: int) -> CsrMatrix:
    """The model's states x states pattern: an edge where some choice has a positive entry."""
    entries = np.repeat(owner, np.diff(transitions.indptr))
    positive = transitions.data > 0
    graph = sp.csr_matrix((np.ones(int(positive.sum()), dtype=np.int8),
                           (entries[positive], transitions.indices[positive])), shape=(n, n))
    graph.sum_duplicates()
    return graph


def _reachable(graph: CsrMatrix, after: IntArray, starts: IntArray) -> IntArray:
    """The pairs reachable from *starts*, sorted: one search over the pair graph (each
    automaton state's copy of *graph*) from a virtual root linked to every start."""
    states, n = after.shape[0], graph.shape[0]
    nnz = graph.indptr[-1]
    indices = np.concatenate([after[q, graph.indices] * n + graph.indices
                              for q in range(states)] + [np.unique(starts)])
    indptr = np.concatenate([graph.indptr[:-1] + q * nnz for q in range(states)]
                            + [[states * nnz, indices.size]])
    size = states * n + 1
    pairs = sp.csr_matrix((np.ones(indices.size, dtype=np.int8), indices, indptr),
                          shape=(size, size))
    order = csgraph.breadth_first_order(pairs, size - 1, directed=True,
                                        return_predecessors=False)
    return np.sort(order[order != size - 1]).astype(np.int64)
