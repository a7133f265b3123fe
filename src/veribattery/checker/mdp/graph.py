"""Qualitative analysis of an MDP: which states reach a target with probability 0 or 1.

The four classic pre-computations (PRISM's names; de Alfaro 1997, Baier & Katoen
2008, §10.6), for ``remain U target``:

* :func:`prob0a` -- probability 0 under *every* strategy (``Pmax = 0``);
* :func:`prob0e` -- probability 0 under *some* strategy (``Pmin = 0``);
* :func:`prob1a` -- probability 1 under every strategy (``Pmin = 1``);
* :func:`prob1e` -- probability 1 under some strategy (``Pmax = 1``).

Everything is a graph search over the positive entries of the choice matrix,
vectorised over whole frontiers; the only Python loops run over the levels or
the rounds of a fixpoint.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._types import BoolArray, CsrMatrix, IntArray
from veribattery._unique import distinct, distinct_first

__all__ = [
    "ChoiceGraph",
    "all_successors_in",
    "almost_surely",
    "any_successor_in",
    "attractor",
    "can_reach",
    "forced_into",
    "prob0a",
    "prob0e",
    "prob1a",
    "prob1e",
    "reached_from",
    "reached_from_root",
    "segments",
    "within_steps",
]


@dataclass(frozen=True, slots=True)
class ChoiceGraph:
    """The positive entries of a choice matrix, forwards and backwards.

    :param owner: the state owning each choice.
    :param successor_ptr: CSR offsets of each choice's successors in *successors*.
    :param successors: the states each choice reaches with positive probability.
    :param predecessor_ptr: per state, offsets of the choices entering it in *predecessors*.
    :param predecessors: the choices with a positive entry into each state.
    """

    owner: IntArray
    successor_ptr: IntArray
    successors: IntArray
    predecessor_ptr: IntArray
    predecessors: IntArray

    @classmethod
    def of(cls, transitions: CsrMatrix, owner: IntArray) -> ChoiceGraph:
        """The graph of *transitions* (choices x states), whose choice *c* belongs to
        state ``owner[c]``."""
        positive = transitions.data > 0
        if transitions.has_canonical_format and bool(positive.all()):
            # (a model with an entry per positive probability is its own pattern: its
            # arrays are shared, not copied)
            forwards = transitions
            pattern = sp.csr_matrix((positive.view(np.int8), transitions.indices,
                                     transitions.indptr), shape=transitions.shape)
        else:
            forwards = pattern = sp.csr_matrix(transitions, copy=True)
            pattern.data = (pattern.data > 0).astype(np.int8)
            pattern.eliminate_zeros()
            pattern.sum_duplicates()
        backwards = pattern.tocsc()
        # (states and choices as scipy keeps them, int32 where they fit: in int64 the
        # graph was a fifth of the mission MDP's peak)
        return cls(owner, forwards.indptr, forwards.indices, backwards.indptr,
                   backwards.indices)

    @property
    def num_states(self) -> int:
        """Number of states (columns)."""
        return int(self.predecessor_ptr.size - 1)

    @property
    def num_choices(self) -> int:
        """Number of choices (rows)."""
        return int(self.successor_ptr.size - 1)

    def choices_into(self, states: IntArray) -> IntArray:
        """The choices with a positive entry into any of *states* (with repeats)."""
        return self.predecessors[segments(self.predecessor_ptr, states)]


def segments(indptr: IntArray, rows: IntArray) -> IntArray:
    """Positions ``indptr[r]:indptr[r + 1]`` of every row *r* of *rows*, concatenated."""
    starts = indptr[rows]
    lengths = indptr[rows + 1] - starts
    total = int(lengths.sum())
    if total == 0:
        return np.empty(0, dtype=np.int64)
    ends = np.cumsum(lengths)
    offsets = np.arange(total, dtype=np.int64) - np.repeat(ends - lengths, lengths)
    return np.asarray(np.repeat(starts, lengths) + offsets, dtype=np.int64)


def all_successors_in(graph: ChoiceGraph, states: BoolArray) -> BoolArray:
    """Per choice: whether every successor lies in *states*."""
    return np.asarray(np.logical_and.reduceat(states[graph.successors],
                                              graph.successor_ptr[:-1]), dtype=bool)


def any_successor_in(graph: ChoiceGraph, states: BoolArray) -> BoolArray:
    """Per choice: whether some successor lies in *states*."""
    return np.asarray(np.logical_or.reduceat(states[graph.successors],
                                             graph.successor_ptr[:-1]), dtype=bool)


def can_reach(graph: ChoiceGraph, through: BoolArray, seeds: BoolArray,
              allowed: BoolArray | None = None) -> BoolArray:
    """States with a path to *seeds* whose states before the last lie in *through*.

    One breadth-first search in C over the reversed graph (the stored predecessor
    lists, already grouped by state: no sort), from a virtual root linked to every
    seed. The seeds themselves are included.

    :param allowed: the choices the paths may use (None: all).
    """
    n = graph.num_states
    moves = through[graph.owner]
    if allowed is not None:
        moves &= allowed
    keep = moves[graph.predecessors]
    kept = np.concatenate([[0], np.cumsum(keep)])
    roots = np.flatnonzero(seeds)
    indptr = np.concatenate([kept[graph.predecessor_ptr], [kept[-1] + roots.size]])
    indices = np.concatenate([graph.owner[graph.predecessors[keep]], roots])
    return reached_from_root(indptr, indices, n)


def within_steps(transitions: CsrMatrix, owner: IntArray, moving: BoolArray,
                 target: BoolArray, k: int) -> BoolArray:
    """States with a path of at most *k* steps to *target* whose states before the last
    are in *moving*: a breadth-first search over the reversed state graph cut at depth
    *k* (in C; a stored 0 counts as an edge, which only keeps a state in)."""
    n = target.size
    if not target.any():
        return np.zeros(n, dtype=bool)
    rows = np.repeat(owner, np.diff(transitions.indptr))
    keep = moving[rows]
    backwards = sp.csr_matrix((np.ones(int(keep.sum())), (transitions.indices[keep], rows[keep])),
                              shape=(n, n))
    distance = csgraph.dijkstra(backwards, directed=True, indices=np.flatnonzero(target),
                                unweighted=True, min_only=True, limit=min(k, n) + 0.5)
    return np.asarray(np.isfinite(distance), dtype=bool)


def reached_from(chain: CsrMatrix, start: int) -> IntArray:
    """The states of the square matrix *chain* reachable from *start* along its positive
    entries (*start* included), sorted: one breadth-first search in C."""
    positive = sp.csr_matrix((chain.data > 0, chain.indices, chain.indptr), shape=chain.shape)
    positive.eliminate_zeros()
    order = csgraph.breadth_first_order(positive, start, directed=True,
                                        return_predecessors=False)
    return np.sort(order).astype(np.int64)


def reached_from_root(indptr: IntArray, indices: IntArray, n: int) -> BoolArray:
    """The states reached from a root ``n`` in the graph of CSR arrays *indptr* and
    *indices* over ``n + 1`` nodes (the root's row last): one breadth-first search in C.

    Made in the dtypes csgraph works in (float64 weights, int32 indices), so that it
    copies nothing.
    """
    index = np.int32 if n < 2**31 - 1 else np.int64
    graph = sp.csr_matrix((np.ones(indices.size), indices.astype(index), indptr.astype(index)),
                          shape=(n + 1, n + 1))
    order = csgraph.breadth_first_order(graph, n, directed=True, return_predecessors=False)
    reached = np.zeros(n + 1, dtype=bool)
    reached[order] = True
    return reached[:n]


def attractor(graph: ChoiceGraph, through: BoolArray, seeds: BoolArray,
              allowed: BoolArray | None = None) -> tuple[BoolArray, IntArray]:
    """:func:`can_reach` with a witness: per state, a choice that moves closer to *seeds*.

    Level by level: a state of *through* joins at level ``d + 1`` with a choice that
    enters level ``d`` with positive probability. Following the witnesses, every step
    has a positive probability of getting one level closer; as long as each choice's
    other successors also keep that property (the caller's *allowed*), *seeds* are
    reached almost surely.

    :return: ``(reached, via)``, *via* the witness choice of each reached non-seed
        state and -1 elsewhere.
    """
    reached = seeds.copy()
    via = np.full(graph.num_states, -1, dtype=np.int64)
    frontier = np.flatnonzero(seeds)
    while frontier.size:
        entering = distinct(graph.choices_into(frontier))
        owners = graph.owner[entering]
        usable = through[owners] & ~reached[owners]
        if allowed is not None:
            usable &= allowed[entering]
        entering, owners = entering[usable], owners[usable]
        owners, first = distinct_first(owners)
        via[owners] = entering[first]
        reached[owners] = True
        frontier = owners
    return reached, via


def forced_into(graph: ChoiceGraph, through: BoolArray, seeds: BoolArray) -> BoolArray:
    """States from which *every* strategy reaches *seeds* with positive probability,
    passing through *through* (the universal attractor: all choices must lead closer).

    A state joins once each of its choices has a successor already in the set;
    the count of choices still missing is kept per state, so each entry of the
    matrix is looked at once over all levels.
    """
    pending = np.bincount(graph.owner, minlength=graph.num_states)
    hit = np.zeros(graph.num_choices, dtype=bool)
    inside = seeds.copy()
    frontier = np.flatnonzero(seeds)
    while frontier.size:
        entering = distinct(graph.choices_into(frontier))
        entering = entering[~hit[entering]]
        hit[entering] = True
        # Per level, work in the size of the level (a bincount over every state per
        # level cost O(levels x states): most of Rmax's pre-pass on the mission MDP).
        candidates, counts = np.unique(graph.owner[entering], return_counts=True)
        pending[candidates] -= counts
        joining = (pending[candidates] == 0) & through[candidates] & ~inside[candidates]
        frontier = candidates[joining]
        inside[frontier] = True
    return inside


def prob0a(graph: ChoiceGraph, remain: BoolArray, target: BoolArray) -> BoolArray:
    """States where ``remain U target`` has probability 0 under every strategy (Pmax = 0)."""
    return ~can_reach(graph, remain & ~target, target)


def prob0e(graph: ChoiceGraph, remain: BoolArray, target: BoolArray) -> BoolArray:
    """States where some strategy makes ``remain U target`` have probability 0 (Pmin = 0)."""
    return ~forced_into(graph, remain & ~target, target)


def prob1a(graph: ChoiceGraph, remain: BoolArray, target: BoolArray,
           zero_somewhere: BoolArray) -> BoolArray:
    """States where ``remain U target`` has probability 1 under every strategy (Pmin = 1).

    Pmin < 1 exactly where a path through ``remain & !target`` leads to a state where
    some strategy gives probability 0: follow it with positive probability, then play
    that strategy.

    :param zero_somewhere: the result of :func:`prob0e` for the same arguments.
    """
    return ~can_reach(graph, remain & ~target, zero_somewhere)


def prob1e(graph: ChoiceGraph, remain: BoolArray, target: BoolArray,
           allowed: BoolArray | None = None) -> BoolArray:
    """States where some strategy makes ``remain U target`` have probability 1 (Pmax = 1).

    The nested fixpoint: the candidate set *u* shrinks to the states that reach
    *target* using only choices that never leave *u*, until it stops changing.
    Both *u* and the choices that move (owned by ``remain & !target & u``, every
    successor in *u*) only shrink, so each round updates them from the states it
    removed, and searches only the edges of the choices still moving. The states a
    search misses take with them every state they leave without a moving choice
    (:func:`_stranded_removed`): the next search would miss those too, and peeling
    them one round each costs a search per layer (hundreds on the mission MDP).

    :param allowed: the choices the strategy may use (None: all).
    """
    through = remain & ~target
    candidate = np.ones(graph.num_states, dtype=bool)
    staying = np.ones(graph.num_choices, dtype=bool) if allowed is None else allowed.copy()
    edges = _ReversedEdges.of(graph)
    roots = np.flatnonzero(target)
    while True:
        moving = staying & (through & candidate)[graph.owner]
        edges = edges.kept(moving)
        shrunk = edges.reaching(roots)
        if np.array_equal(shrunk, candidate):
            return candidate
        missed = np.flatnonzero(candidate & ~shrunk)
        candidate = _stranded_removed(graph, shrunk, moving & shrunk[graph.owner], staying,
                                      missed)


def _stranded_removed(graph: ChoiceGraph, candidate: BoolArray, moving: BoolArray,
                      staying: BoolArray, removed: IntArray) -> BoolArray:
    """*candidate* (from which *removed* has left) less every state left without a
    moving choice once the choices into removed states stop staying (updated in place).

    A state of *candidate* is one of *target* (it owns no moving choice and never
    leaves) or owns a moving choice. Each state counts its moving choices still
    staying; level by level, a removed state's entering choices stop staying, their
    owners' counts drop, and an owner at 0 is removed in turn -- each choice is
    looked at once, so all levels cost one pass over the matrix.

    :param moving: the choices of *candidate*'s states that moved in the last search.
    """
    left = np.bincount(graph.owner[moving], minlength=graph.num_states)
    choice_seen = np.empty(graph.num_choices, dtype=np.int64)
    state_seen = np.empty(graph.num_states, dtype=np.int64)
    frontier = removed
    while frontier.size:
        entering = graph.choices_into(frontier)
        entering = _distinct(entering[staying[entering]], choice_seen)
        staying[entering] = False
        owners = graph.owner[entering[moving[entering]]]
        owners = owners[candidate[owners]]
        np.subtract.at(left, owners, 1)
        frontier = _distinct(owners[left[owners] == 0], state_seen)
        candidate[frontier] = False
    return candidate


def _distinct(values: IntArray, seen: IntArray) -> IntArray:
    """*values* once each, in linear time (*seen*: scratch indexed by value).

    Of a repeated value's writes into *seen* exactly one lands (whichever), so exactly
    one of its occurrences reads its own position back.
    """
    order = np.arange(values.size, dtype=np.int64)
    seen[values] = order
    return np.asarray(values[seen[values] == order], dtype=np.int64)


@dataclass(frozen=True, slots=True)
class _ReversedEdges:
    """Edges ``successor -> owner`` of a set of choices, grouped by successor.

    :param num_states: the number of states.
    :param owner: the state owning each choice of the graph.
    :param heads: per edge, the successor (nondecreasing).
    :param choices: per edge, its choice.
    """

    num_states: int
    owner: IntArray
    heads: IntArray
    choices: IntArray

    @classmethod
    def of(cls, graph: ChoiceGraph) -> _ReversedEdges:
        """Every edge of *graph*."""
        heads = np.repeat(np.arange(graph.num_states, dtype=np.int64),
                          np.diff(graph.predecessor_ptr))
        return cls(graph.num_states, graph.owner, heads, graph.predecessors)

    def kept(self, moves: BoolArray) -> _ReversedEdges:
        """The edges of the choices *moves*."""
        keep = moves[self.choices]
        return _ReversedEdges(self.num_states, self.owner, self.heads[keep],
                              self.choices[keep])

    def reaching(self, roots: IntArray) -> BoolArray:
        """The states with a path along the edges to *roots* (the roots included)."""
        n = self.num_states
        counts = np.bincount(self.heads, minlength=n)
        indptr = np.concatenate([[0], np.cumsum(counts), [self.heads.size + roots.size]])
        indices = np.concatenate([self.owner[self.choices], roots])
        return reached_from_root(indptr, indices, n)


def almost_surely(graph: ChoiceGraph, remain: BoolArray, target: BoolArray,
                  allowed: BoolArray | None = None) -> tuple[BoolArray, IntArray]:
    """:func:`prob1e` and a witness: per state of it outside *target*, a choice that stays
    in the set and moves closer to *target* (-1 elsewhere). Following the witnesses
    reaches *target* with probability 1.
    """
    sure = prob1e(graph, remain, target, allowed)
    staying = all_successors_in(graph, sure)
    if allowed is not None:
        staying &= allowed
    _, via = attractor(graph, remain & ~target & sure, target, staying)
    return sure, via
