"""The product of a model with a deterministic automaton.

A product state is a pair ``(s, q)``: the model in *s*, the automaton in *q* after
reading the letters of the states so far, *s*'s included. A choice of *s* leads from
``(s, q)`` to ``(t, successor[q, letter(t)])`` with the choice's probability of *t*, so
the product has exactly the model's choices, one copy per automaton state it meets. A
path of the model from *s* corresponds to one path of the product from
``(s, successor[initial, letter(s)])``, its *start*; the automaton being deterministic,
strategies correspond too, and a formula's probability (its optimum) from *s* is the
product's acceptance probability (optimum) from the start of *s*.

Built without a loop over states (:func:`product`): array operations on the model's rows
and the automaton's successor table, and at most one breadth-first search in C.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from veribattery._types import CsrMatrix, IntArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.mdp.graph import reached_from_root, segments

__all__ = ["Automaton", "Product", "product"]


class Automaton(Protocol):
    """A complete deterministic automaton: ``successor[q, column]`` from *initial*."""

    @property
    def initial(self) -> int: ...

    @property
    def successor(self) -> NDArray[np.integer[Any]]: ...


@dataclass(frozen=True, slots=True)
class Product:
    """The product of a model (choices x states) and an automaton, over the pairs that
    can be entered (:func:`product`).

    :param transitions: product choices x product states; the choices of a product state
        are its model state's, in their order.
    :param row_groups: per product state, the offsets of its choices.
    :param choices: per product choice, the model choice it copies.
    :param model_indptr: the model's row offsets (where :attr:`entries` are read).
    :param model_state: per product state, its model state.
    :param automaton_state: per product state, its automaton state.
    :param start: per model state, the product state a path from it starts in.
    """

    transitions: CsrMatrix
    row_groups: IntArray
    choices: IntArray
    model_indptr: IntArray
    model_state: IntArray
    automaton_state: IntArray
    start: IntArray

    @property
    def num_states(self) -> int:
        """Number of product states."""
        return int(self.model_state.size)

    @property
    def entries(self) -> IntArray:
        """Per stored entry of *transitions*, the model's entry it copies (where exact
        probabilities are read; made when asked, as floats never need it)."""
        return segments(self.model_indptr, self.choices)

    def at_starts(self, found: Bounds) -> Bounds:
        """Per model state, the product's *found* values at its start."""
        start = self.start
        return Bounds(found.value[start], found.lower[start], found.upper[start])


def product(transitions: CsrMatrix, row_groups: IntArray, automaton: Automaton,
            column: IntArray) -> Product:
    """The product of the model (*transitions*, choices x states, grouped by *row_groups*)
    with the deterministic *automaton*, each state reading its *column* of the automaton's
    table (its letter), from every model state.

    A pair ``(t, q')`` can be entered only if ``q'`` is where some automaton state goes on
    *t*'s letter; those pairs (the starts among them) are closed under the product's
    steps, so the product is built over them with array operations alone. For ``G F a``
    an automaton state is the last letter's verdict: one pair per model state, every one
    a start. Where a state has several, the pairs no start reaches are dropped after one
    search. Pairs are numbered model-state-major (``t * Q + q'``), so each product row's
    columns ascend as its model row's do.
    """
    n, states = int(row_groups.size - 1), int(automaton.successor.shape[0])
    after = np.asarray(automaton.successor[:, column], dtype=np.int64)  # (q, t) -> q'
    enterable = np.zeros((n, states), dtype=bool)
    for row in after:  # one vectorised pass per automaton state
        enterable[np.arange(n), row] = True
    pairs = np.flatnonzero(enterable)  # t * Q + q', ascending
    del enterable
    number = np.full(n * states, -1, dtype=np.int64)
    number[pairs] = np.arange(pairs.size, dtype=np.int64)
    model_state, automaton_state = pairs // states, pairs % states
    sizes = np.diff(row_groups)[model_state]
    groups = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    copied = segments(np.asarray(row_groups, dtype=np.int64), model_state)
    rows = transitions[copied]
    # per entry: t * Q + q, then t * Q + after[q, t], the pair the entry enters
    key = rows.indices.astype(np.int64) * states
    q = np.repeat(np.repeat(automaton_state.astype(np.int32), sizes), np.diff(rows.indptr))
    key += q
    entered = after.T.reshape(-1)[key]
    key -= q
    del q
    key += entered
    del entered
    columns = number[key]
    del key
    matrix = sp.csr_matrix((rows.data, columns, rows.indptr), shape=(copied.size, pairs.size))
    del rows, columns  # (the matrix holds its own index copy: 12 bytes an entry, freed)
    starts = number[np.arange(n, dtype=np.int64) * states + after[automaton.initial]]
    joint = Product(matrix, groups, copied, np.asarray(transitions.indptr, dtype=np.int64),
                    model_state, automaton_state, starts)
    # Where some state can be entered in several automaton states, part of those pairs
    # may be unreachable (F a & G b: "failed" and "waiting" at every state): dropping
    # them makes the solvers' systems smaller (1.2 million pairs to 0.6 on the mission MDP)
    return _reachable_part(joint) if pairs.size > n else joint


def _reachable_part(joint: Product) -> Product:
    """*joint* restricted to the pairs reachable from the starts (one search in C over
    the pair graph: a pair's choices are contiguous, so are their entries)."""
    size = joint.num_states
    indptr = joint.transitions.indptr[joint.row_groups]
    starts = np.unique(joint.start)
    reached = reached_from_root(np.concatenate([indptr, [indptr[-1] + starts.size]]),
                                np.concatenate([joint.transitions.indices, starts]), size)
    if reached.all():
        return joint
    kept = np.flatnonzero(reached)
    number = np.full(size, -1, dtype=np.int64)
    number[kept] = np.arange(kept.size, dtype=np.int64)
    rows = segments(joint.row_groups, kept)
    sizes = np.diff(joint.row_groups)[kept]
    picked = joint.transitions[rows]
    matrix = sp.csr_matrix((picked.data, number[picked.indices], picked.indptr),
                           shape=(rows.size, kept.size))
    return Product(matrix, np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                   joint.choices[rows], joint.model_indptr, joint.model_state[kept],
                   joint.automaton_state[kept], number[joint.start])
