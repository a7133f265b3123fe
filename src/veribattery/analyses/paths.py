"""The k most probable paths of a DTMC from a state into a target set.

A path's probability is the product of its transition probabilities, so the most
probable paths are the shortest ones under the weights ``-log p``. Paths end at
their first target state; they may go round cycles any number of times.

The enumeration is Eppstein's sidetrack scheme, evaluated lazily:

1. One backward Dijkstra search from the target set (in C, via
   :mod:`scipy.sparse.csgraph`) gives every state's distance ``d`` to the
   target and its *tree edge*, the first edge of one shortest path.
2. Every other edge ``(u, v)`` is a *sidetrack* costing
   ``delta = w(u, v) + d(v) - d(u) >= 0``. A path is the tree path from the
   source with a sequence of sidetracks taken on the way, and its cost is
   ``d(source)`` plus their deltas: paths and sidetrack sequences correspond one
   to one.
3. Sequences are enumerated best first. The sidetracks available after the last
   one (ending in ``v``) are those out of the tree path from ``v``, sorted by
   delta (``H(v)``, built on demand). A popped sequence has at most two children:
   itself plus the first sidetrack of ``H(head)``, and itself with its last
   sidetrack replaced by the next one of the list that sidetrack came from. Every
   sequence has exactly one parent that is no more costly, so each path is found
   exactly once and in order of probability.

The work per path is proportional to the length of the paths involved, never to
the number of states.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.errors import CheckError

__all__ = ["ProbablePath", "most_probable_paths"]

#: Weight standing in for ``-log 1 = 0``, so that no sparse operation drops the edge.
_ZERO = float(np.finfo(np.float64).tiny)


@dataclass(frozen=True, slots=True)
class ProbablePath:
    """One path: its states (the first the source, the last in the target) and probability."""

    states: IntArray
    probability: float
    #: ``log10`` of the probability: still finite where the product underflows to 0
    #: (a path of hundreds of steps on a large farm).
    log10_probability: float

    @property
    def probability_text(self) -> str:
        """The probability to 6 significant digits, also below the float range."""
        if self.probability > 0 or not math.isfinite(self.log10_probability):
            return f"{self.probability:.6g}"
        exponent = math.floor(self.log10_probability)
        mantissa = f"{10 ** (self.log10_probability - exponent):.6g}"
        if mantissa == "10":  # 9.9999996... rounds up to the next power of ten
            mantissa, exponent = "1", exponent + 1
        return f"{mantissa}e{exponent}"

    @property
    def steps(self) -> int:
        """Number of transitions."""
        return int(self.states.size) - 1


@dataclass(frozen=True, slots=True)
class _Tree:
    """Shortest-path tree towards the target, and each edge's sidetrack cost."""

    P: CsrMatrix
    rows: IntArray  # source state of each stored edge
    weight: FloatArray  # -log p of each edge (inf for edges out of the target)
    dist: FloatArray  # distance of each state to the target
    next_state: IntArray  # tree successor (-1 in the target or where unreachable)
    delta: FloatArray  # sidetrack cost of each edge (inf: not a sidetrack)


def most_probable_paths(
    P: CsrMatrix, source: int, target: BoolArray, count: int
) -> tuple[ProbablePath, ...]:
    """The *count* most probable paths from *source* to its first visit of *target*.

    Fewer are returned when fewer paths exist (e.g. none when *target* is
    unreachable). Ties are broken arbitrarily but deterministically.

    :param P: row-stochastic CSR transition matrix.
    :param source: the start state.
    :param target: mask of the target states.
    :param count: how many paths (at least 1).
    :raises CheckError: when *count* is below 1.
    """
    if count < 1:
        raise CheckError(f"the number of paths must be at least 1, not {count}")
    if target[source]:
        return (ProbablePath(np.array([source], dtype=np.int64), 1.0, 0.0),)
    tree = _shortest_tree(P, target)
    if not math.isfinite(tree.dist[source]):
        return ()
    return tuple(_enumerate(tree, source, count))


def _shortest_tree(P: CsrMatrix, target: BoolArray) -> _Tree:
    n = P.shape[0]
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(P.indptr))
    live = (P.data > 0) & ~target[rows]
    with np.errstate(divide="ignore"):
        weight = np.where(live, np.maximum(-np.log(P.data), _ZERO), np.inf)
    # Reversed graph plus a virtual source n joined to every target state.
    goals = np.flatnonzero(target)
    src = np.concatenate([P.indices[live], np.full(goals.size, n)])
    dst = np.concatenate([rows[live], goals])
    w = np.concatenate([weight[live], np.full(goals.size, _ZERO)])
    graph = sp.csr_matrix((w, (src, dst)), shape=(n + 1, n + 1))
    dist, pred = csgraph.dijkstra(graph, directed=True, indices=n, return_predecessors=True)
    next_state = np.where(pred[:n] == n, -1, pred[:n]).astype(np.int64)
    next_state[~np.isfinite(dist[:n])] = -1
    dist = dist[:n] - _ZERO  # the virtual edge's stand-in weight
    return _Tree(P, rows, weight, dist, next_state, _deltas(P, rows, weight, dist, next_state))


def _deltas(P: CsrMatrix, rows: IntArray, weight: FloatArray, dist: FloatArray,
            next_state: IntArray) -> FloatArray:
    cols = P.indices
    sidetrack = np.isfinite(weight) & np.isfinite(dist[cols]) & (cols != next_state[rows])
    with np.errstate(invalid="ignore"):
        delta = np.maximum(weight + dist[cols] - dist[rows], 0.0)
    return np.where(sidetrack, delta, np.inf)


@dataclass(slots=True)
class _Candidates:
    """The sorted sidetrack lists ``H(v)``, built once per head state."""

    tree: _Tree
    lists: dict[int, IntArray]

    def of(self, head: int) -> IntArray:
        found = self.lists.get(head)
        if found is None:
            path = _tree_path(self.tree, head)
            indptr = self.tree.P.indptr
            edges = np.concatenate([np.arange(indptr[u], indptr[u + 1]) for u in path[:-1]]
                                   or [np.zeros(0, dtype=np.int64)])
            edges = edges[np.isfinite(self.tree.delta[edges])]
            found = edges[np.argsort(self.tree.delta[edges], kind="stable")]
            self.lists[head] = found
        return found


def _tree_path(tree: _Tree, start: int) -> list[int]:
    """States of the tree path from *start* to the target (both included)."""
    path = [start]
    while tree.next_state[path[-1]] >= 0:
        path.append(int(tree.next_state[path[-1]]))
    return path


def _enumerate(tree: _Tree, source: int, count: int) -> list[ProbablePath]:
    candidates = _Candidates(tree, {})
    # Heap entries: cost, tie-breaker, sidetrack sequence, (owner head, position) of the last.
    heap: list[tuple[float, int, tuple[int, ...], tuple[int, int]]] = [
        (float(tree.dist[source]), 0, (), (source, -1))
    ]
    found: list[ProbablePath] = []
    pushed = 1
    while heap and len(found) < count:
        cost, _, seq, (owner, pos) = heapq.heappop(heap)
        found.append(_path_of(tree, source, seq))
        for child in _children(tree, candidates, source, cost, seq, owner, pos):
            heapq.heappush(heap, (child[0], pushed, child[1], child[2]))
            pushed += 1
    return found


def _children(
    tree: _Tree, candidates: _Candidates, source: int, cost: float,
    seq: tuple[int, ...], owner: int, pos: int,
) -> list[tuple[float, tuple[int, ...], tuple[int, int]]]:
    children = []
    head = int(tree.P.indices[seq[-1]]) if seq else source
    after = candidates.of(head)
    if after.size:
        children.append((cost + float(tree.delta[after[0]]), (*seq, int(after[0])), (head, 0)))
    if seq:
        siblings = candidates.of(owner)
        if pos + 1 < siblings.size:
            edge = int(siblings[pos + 1])
            swapped = cost - float(tree.delta[seq[-1]]) + float(tree.delta[edge])
            children.append((swapped, (*seq[:-1], edge), (owner, pos + 1)))
    return children


def _path_of(tree: _Tree, source: int, seq: tuple[int, ...]) -> ProbablePath:
    """The states of the path that takes the sidetracks *seq*, and its exact probability."""
    states = [source]
    for edge in seq:
        tail = int(tree.rows[edge])
        while states[-1] != tail:
            states.append(int(tree.next_state[states[-1]]))
        states.append(int(tree.P.indices[edge]))
    states.extend(_tree_path(tree, states[-1])[1:])
    path = np.asarray(states, dtype=np.int64)
    probs = np.asarray(tree.P[path[:-1], path[1:]]).ravel()
    log10 = float(np.sum(np.log10(probs)))
    return ProbablePath(path, float(10.0 ** log10), log10)
