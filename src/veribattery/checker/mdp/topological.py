"""A first approximation of the optimum: value iteration in topological order.

Policy iteration from a strategy that merely makes progress towards the goal
spends many rounds, each a sparse LU of the whole system, before the values of
the last classes settle (consensus's ``c2``: 38). Here the classes are taken in
the order Storm's topological solver takes them: the strongly connected
components of the *class graph* (an edge ``c -> d`` where a row of class *c*
reaches class *d*), successors first, so that every component is solved once
everything it reads is final:

* components are grouped in *levels*: a level holds the components all of whose
  successors lie in lower levels, so the components of a level read only final
  values and not each other (the longest path down to the known states);
* a *trivial* component (one class: a row's entries in its own class are folded
  into ``s_a``, so a class never reads itself) is final after one Bellman step,
  taken for all the trivial components of a level at once;
* the *cyclic* components of a level are solved together on their own equations
  (the rest of the system read as constants): a few Jacobi sweeps of value
  iteration, then policy iteration, each round a sparse LU of just those classes.

The only Python loops run over the levels and the rounds. The result is an
approximation like any other: the caller evaluates the greedy strategy of these
values on the whole system (one LU, needed for the certificate anyway), improves
it further if it can, and the certificate decides what the values are worth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._sparse import csr_rows
from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.linalg.topological import condensation
from veribattery.checker.mdp.graph import segments
from veribattery.checker.mdp.solve import (
    POLICY_TOLERANCE,
    Evaluation,
    evaluate,
    improve,
    is_improper,
    strategy_lu,
    tightest_among_ties,
)
from veribattery.checker.mdp.system import ChoiceSystem, ClassRows, Objective

__all__ = ["LEVEL_LIMIT", "LevelOrder", "Levels", "class_levels", "greedy_rows", "is_proper",
           "rows_after_sweeps", "topological_policy_iteration", "topological_values"]

#: Systems with more levels than this are left to policy iteration from the progress
#: strategy (a Python iteration per level: a chain of 10^6 classes has 10^6 levels).
LEVEL_LIMIT = 50_000
#: Jacobi sweeps over a level's cyclic components before their policy iteration ...
SWEEPS = 100
#: ... stopped early once no value moves by more than this, relative.
SWEEP_TOLERANCE = 2.0**-48
#: A row replaces the current one only if better by this much, relative (policy
#: iteration's tolerance); rows this close to the best count as tied.
TIE = POLICY_TOLERANCE
#: Policy-iteration rounds on one level's cyclic components.
LOCAL_ROUNDS = 200


def topological_policy_iteration(system: ChoiceSystem, objective: Objective,
                                 known: FloatArray, offset: FloatArray | None,
                                 preferred: IntArray, levels: Levels | None = None, *,
                                 progress: Progress | None = None) -> Evaluation | None:
    """Policy iteration on the whole system from the greedy strategy of
    :func:`topological_values` (ties kept on *preferred*), or None where that does not
    apply: more than :data:`LEVEL_LIMIT` levels, or a greedy strategy that does not
    reach the known states (minimal rewards) or whose system is singular. The caller
    then starts from *preferred*, the progress strategy.

    :param levels: the system's :func:`class_levels`, if the caller has them."""
    levels = class_levels(system) if levels is None else levels
    if not levels.within_limit:
        return None
    values = topological_values(system, objective, known, offset, preferred, levels,
                                progress=progress)
    rows = greedy_rows(system.images(values, known, offset), system.groups[:-1], objective,
                       preferred)
    if objective == "min" and offset is not None and not is_proper(system, rows):
        return None
    first = evaluate(system, rows, known, offset)
    if first is None or is_improper(first.values):
        return None
    # Each evaluation is handed on, not kept by a name here: a call's arguments belong to
    # the callee (CPython >= 3.11), which drops each one as a better one replaces it, so
    # at most two solvers live at once (firewire: 300 -> 285 MB peak).
    handed = [first]
    del first
    return tightest_among_ties(system, objective, known, offset,
                               improve(system, objective, known, offset, handed.pop(),
                                       progress=progress))


@dataclass(frozen=True, slots=True)
class Levels:
    """The classes of a system ordered by level, the trivial ones first in each.

    :param classes: every class once, level by level from the known states back.
    :param starts: per level, the position of its first class, then ``size``.
    :param cyclic_from: per level, the position of its first class that lies in a
        cyclic component (its trivial classes come before).
    """

    classes: IntArray
    starts: IntArray
    cyclic_from: IntArray

    @property
    def count(self) -> int:
        """The number of levels."""
        return int(self.starts.size - 1)

    @property
    def within_limit(self) -> bool:
        """Whether there are few enough levels to take them one by one (:data:`LEVEL_LIMIT`)."""
        return self.count <= LEVEL_LIMIT

    @property
    def acyclic(self) -> bool:
        """Whether every component is trivial (the class graph has no cycle)."""
        return bool(np.array_equal(self.cyclic_from, self.starts[1:]))


def class_levels(system: ChoiceSystem) -> Levels:
    """The levels of the condensation of *system*'s class graph."""
    n = system.size
    graph = _class_graph(system)
    found = condensation(graph)
    component = np.empty(n, dtype=np.int64)
    component[found.order] = np.repeat(np.arange(found.count, dtype=np.int64), found.sizes)
    depth = _longest_paths(found.count, *_edges_across(graph, component))
    level = depth[component]
    cyclic = found.sizes[component] > 1
    order = np.lexsort((cyclic, level)).astype(np.int64)
    count = int(depth.max(initial=-1)) + 1
    starts = np.zeros(count + 1, dtype=np.int64)
    np.cumsum(np.bincount(level, minlength=count), out=starts[1:])
    trivial = np.bincount(level[~cyclic], minlength=count)
    return Levels(order, starts, starts[:-1] + trivial)


def _class_graph(system: ChoiceSystem) -> sp.csr_matrix:
    """The class graph: an entry ``c -> d`` for each entry of a row of class *c* in the
    column of class *d* (repeats kept). A class's rows are contiguous, so its entries
    are read from the system's matrix as they lie, without a copy of its columns."""
    off = system.off
    inner = off.indices < system.size
    kept = np.zeros(inner.size + 1, dtype=np.int64)
    np.cumsum(inner, out=kept[1:])
    indptr = kept[off.indptr[system.groups]]
    indices = off.indices[inner]
    return sp.csr_matrix((np.ones(indices.size, dtype=np.int8), indices, indptr),
                         shape=(system.size, system.size))


def _edges_across(graph: sp.csr_matrix, component: IntArray) -> tuple[IntArray, IntArray]:
    """The edges of *graph* between different components, as component pairs."""
    src = component[np.repeat(np.arange(graph.shape[0], dtype=np.int64), np.diff(graph.indptr))]
    dst = component[graph.indices]
    across = src != dst
    return src[across], dst[across]


def _longest_paths(count: int, src: IntArray, dst: IntArray) -> IntArray:
    """Per component, the length of its longest path down to a sink of the
    condensation (edges *src* -> *dst*), by peeling the sinks a level at a time."""
    graph = sp.csr_matrix((np.ones(src.size, dtype=np.int32), (src, dst)), shape=(count, count))
    graph.sum_duplicates()
    reverse = sp.csr_matrix(graph.T)
    reverse_ptr = reverse.indptr.astype(np.int64)
    pending = np.diff(graph.indptr).astype(np.int64)  # successors not yet levelled
    depth = np.empty(count, dtype=np.int64)
    frontier = np.flatnonzero(pending == 0)
    level = 0
    while frontier.size:
        depth[frontier] = level
        level += 1
        predecessors = reverse.indices[segments(reverse_ptr, frontier)]
        touched, times = np.unique(predecessors, return_counts=True)
        pending[touched] -= times
        frontier = touched[pending[touched] == 0]
    return depth


def topological_values(system: ChoiceSystem, objective: Objective, known: FloatArray,
                       offset: FloatArray | None, preferred: IntArray,
                       levels: Levels, *, progress: Progress | None = None) -> FloatArray:
    """Approximately optimal values of the classes, level by level.

    :param preferred: per class, a row kept wherever it ties with the best (the
        progress strategy); for minimal rewards also the start of every local policy
        iteration, as it must be proper there.
    :param progress: told ``(levels done, levels, "levels")`` after each level.
    """
    ordered = LevelOrder.of(system, offset, levels)
    full = np.concatenate([np.zeros(system.size), known])
    rank = np.full(full.size, -1, dtype=np.int64)  # scratch: a class's local index
    reduce = np.maximum if objective == "max" else np.minimum
    for k in range(levels.count):
        lo, mid, hi = (int(levels.starts[k]), int(levels.cyclic_from[k]),
                       int(levels.starts[k + 1]))
        if mid > lo:
            images = ordered.images(lo, mid, full)
            full[levels.classes[lo:mid]] = reduce.reduceat(images, ordered.local_starts(lo, mid))
        if hi > mid:
            classes = levels.classes[mid:hi]
            rank[classes] = np.arange(classes.size)
            local = _Local.of(ordered, mid, hi, full, rank)
            rank[classes] = -1
            proper_only = objective == "min" and offset is not None
            start = ordered.preferred(system, preferred, classes, mid)
            full[classes] = local.optimum(objective, start, proper_only=proper_only)
        if progress is not None:
            progress(k + 1, levels.count, "levels")
    return full[: system.size]


@dataclass(frozen=True, slots=True)
class LevelOrder:
    """The rows of a system read in level order (each level's rows contiguous).

    The rows are gathered a level at a time, not copied once in level order: the copy
    was a second matrix as large as the system's, alive through the whole pass (the
    mission MDP: 30 MB of its 307 MB peak).

    :param rows: per position in level order, the row of the system there.
    :param row_starts: per class position in level order, its first row here (then the
        number of rows).
    """

    system: ChoiceSystem
    offset: FloatArray | None
    rows: IntArray
    row_starts: IntArray

    @classmethod
    def of(cls, system: ChoiceSystem, offset: FloatArray | None, levels: Levels) -> LevelOrder:
        rows = segments(system.groups, levels.classes)
        counts = np.diff(system.groups)[levels.classes]
        row_starts = np.zeros(levels.classes.size + 1, dtype=np.int64)
        np.cumsum(counts, out=row_starts[1:])
        return cls(system, offset, rows, row_starts)

    def row_range(self, lo: int, hi: int) -> tuple[int, int]:
        """The rows (here) of the classes at positions ``lo..hi``."""
        return int(self.row_starts[lo]), int(self.row_starts[hi])

    def block(self, first: int, last: int) -> sp.csr_matrix:
        """The rows at positions ``first..last`` (here), in this order, each with its
        entries in their stored order (so every product sums the same terms alike)."""
        off, rows = self.system.off, self.rows[first:last]
        if rows.size and int(rows[-1]) - int(rows[0]) == rows.size - 1 and bool(
                np.all(np.diff(rows) == 1)):
            # (a view: consecutive rows; slicing would copy them, and a model of a
            # thousand levels would slice its whole matrix piece by piece)
            return csr_rows(off, int(rows[0]), int(rows[-1]) + 1)
        return sp.csr_matrix(off[rows])

    def per_row(self, values: FloatArray, first: int, last: int) -> FloatArray:
        """*values* (one per row of the system) of the rows at positions ``first..last``."""
        return np.asarray(values[self.rows[first:last]])

    def images(self, lo: int, hi: int, full: FloatArray) -> FloatArray:
        """``G_a(x)`` of the rows of the classes at positions ``lo..hi``."""
        first, last = self.row_range(lo, hi)
        numerator = self.block(first, last) @ full
        if self.offset is not None:
            numerator = numerator + self.per_row(self.offset, first, last)
        with np.errstate(over="ignore"):  # (not rigorous: beyond the doubles, inf)
            return np.asarray(numerator / self.per_row(self.system.leave, first, last),
                              dtype=np.float64)

    def local_starts(self, lo: int, hi: int) -> IntArray:
        """The first row of each class at positions ``lo..hi``, from the first one's."""
        return np.asarray(self.row_starts[lo:hi] - self.row_starts[lo], dtype=np.int64)

    def preferred(self, system: ChoiceSystem, rows: IntArray, classes: IntArray,
                  lo: int) -> IntArray:
        """The rows *rows* (per class, of the system) of *classes* (at positions
        ``lo..``), numbered locally from the first one's first row."""
        first = self.row_starts[lo:lo + classes.size] - self.row_starts[lo]
        return np.asarray(first + (rows[classes] - system.groups[classes]), dtype=np.int64)


@dataclass(frozen=True, slots=True)
class _Local:
    """The equations of some classes with the rest of the system read as constants:
    ``G_a(x) = (inner_a x + constant_a) / leave_a``."""

    inner: sp.csr_matrix
    constant: FloatArray
    leave: FloatArray
    starts: IntArray
    layout: ClassRows

    @classmethod
    def of(cls, ordered: LevelOrder, lo: int, hi: int, full: FloatArray,
           rank: IntArray) -> _Local:
        first, last = ordered.row_range(lo, hi)
        block = ordered.block(first, last)
        local = rank[block.indices]
        inside = local >= 0
        outside = sp.csr_matrix((np.where(inside, 0.0, block.data), block.indices,
                                 block.indptr), shape=block.shape)
        constant = np.asarray(outside @ full, dtype=np.float64)
        if ordered.offset is not None:
            constant = constant + ordered.per_row(ordered.offset, first, last)
        inner = sp.csr_matrix((np.where(inside, block.data, 0.0), np.maximum(local, 0),
                               block.indptr), shape=(last - first, hi - lo))
        inner.eliminate_zeros()
        starts = ordered.local_starts(lo, hi)
        return cls(inner, constant, ordered.per_row(ordered.system.leave, first, last), starts,
                   ClassRows.of(np.append(starts, last - first)))

    @property
    def size(self) -> int:
        return int(self.starts.size)

    def images(self, x: FloatArray) -> FloatArray:
        return np.asarray((self.inner @ x + self.constant) / self.leave, dtype=np.float64)

    def optimum(self, objective: Objective, preferred: IntArray, *,
                proper_only: bool) -> FloatArray:
        """Sweeps, then policy iteration from their greedy strategy (from *preferred*
        if *proper_only*, or if the greedy one is singular)."""
        x = np.zeros(self.size)
        for _ in range(SWEEPS):
            following = self.layout.best(self.images(x), objective)
            settled = np.all(np.abs(following - x) <= SWEEP_TOLERANCE * np.abs(following))
            x = following
            if settled:
                break
        rows = preferred if proper_only else greedy_rows(self.images(x), self.starts,
                                                          objective, preferred)
        values = self._evaluated(rows)
        if values is None and not proper_only:
            rows, values = preferred, self._evaluated(preferred)
        if values is None:
            return x
        return self._improved(objective, rows, values)

    def _improved(self, objective: Objective, rows: IntArray, values: FloatArray) -> FloatArray:
        """Policy iteration from the strategy *rows* of *values*, until no switch makes a
        value better by more than :data:`TIE` (rounding noise cannot make it cycle)."""
        for _ in range(LOCAL_ROUNDS):
            following = greedy_rows(self.images(values), self.starts, objective, rows)
            if np.array_equal(following, rows):
                break
            candidate = self._evaluated(following)
            if candidate is None:
                break
            gain = candidate - values if objective == "max" else values - candidate
            rows, values, moved = following, candidate, gain > TIE * np.abs(candidate)
            if not moved.any():
                break
        return values

    def _evaluated(self, rows: IntArray) -> FloatArray | None:
        """The values of the strategy *rows*, or None if its system is singular or its
        values are not finite and nonnegative (it stays among these classes)."""
        matrix = sp.csc_matrix(sp.diags(self.leave[rows]) - self.inner[rows])
        try:
            values = np.asarray(strategy_lu(matrix).solve(self.constant[rows]), dtype=np.float64)
        except RuntimeError:
            return None
        scale = float(np.max(np.abs(values), initial=1.0))
        if not np.all(np.isfinite(values)) or np.any(values < -1e-9 * scale):
            return None
        return values


def rows_after_sweeps(system: ChoiceSystem, known: FloatArray, offset: FloatArray | None,
                      current: Evaluation) -> IntArray:
    """The greedy strategy (ties kept on *current*'s rows) of the values after up to
    :data:`SWEEPS` Jacobi sweeps of maximising value iteration from *current*'s values.

    A strategy's values lie below the maximum, and the sweeps only raise them towards
    it, a little everywhere at once -- where each round of policy iteration moves a
    strategy one switch further: on the tied rows of zeroconf (K=4) twenty rounds,
    and two or three after the sweeps.
    """
    x = current.values
    for _ in range(SWEEPS):
        following = np.maximum(x, system.best(system.images(x, known, offset), "max"))
        settled = np.all(np.abs(following - x) <= SWEEP_TOLERANCE * np.abs(following))
        x = following
        if settled:
            break
    return greedy_rows(system.images(x, known, offset), system.groups[:-1], "max",
                       current.rows)


def greedy_rows(images: FloatArray, starts: IntArray, objective: Objective,
                preferred: IntArray) -> IntArray:
    """Per class (rows from *starts* on), the *preferred* row where it ties with the
    best image within :data:`TIE`, else the first row attaining the best.

    :param images: every row's image, rows grouped by class.
    """
    reduce = np.maximum if objective == "max" else np.minimum
    best = reduce.reduceat(images, starts)
    owner = np.repeat(np.arange(starts.size), np.diff(np.append(starts, images.size)))
    hits = images == best[owner]
    first = np.minimum.reduceat(np.where(hits, np.arange(images.size), images.size), starts)
    now = images[preferred]
    with np.errstate(invalid="ignore"):
        tied = np.abs(best - now) <= TIE * np.maximum(np.abs(best), np.abs(now))
    return np.asarray(np.where(tied | (now == best), preferred, first), dtype=np.int64)


def is_proper(system: ChoiceSystem, rows: IntArray) -> bool:
    """Whether the strategy *rows* reaches the known states from every class (with
    positive probability, so almost surely: it is memoryless on finitely many)."""
    n = system.size
    chosen = sp.csr_matrix(system.off[rows])
    exits = np.diff(sp.csr_matrix(chosen[:, n:]).indptr) > 0
    inner = sp.coo_matrix(chosen[:, :n])
    # Backwards from a node n that every class with an exit leads to.
    src = np.concatenate([inner.col, np.full(int(exits.sum()), n)])
    dst = np.concatenate([inner.row, np.flatnonzero(exits)])
    backwards = sp.csr_matrix((np.ones(src.size, dtype=np.int8), (src, dst)), shape=(n + 1, n + 1))
    reached: BoolArray = np.zeros(n + 1, dtype=bool)
    reached[csgraph.breadth_first_order(backwards, n, directed=True,
                                        return_predecessors=False)] = True
    return bool(reached[:n].all())
