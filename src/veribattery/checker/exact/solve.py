"""Exact solution of ``x = A x + b`` on the maybe states, SCC by SCC, in rationals.

After the qualitative pre-pass every maybe state leaves the maybe set with
positive probability eventually, so ``I - A`` restricted to any set of maybe
states -- in particular to each strongly connected component -- is a
nonsingular M-matrix. Its leading principal minors are therefore positive, and
Gaussian elimination *without pivoting* never meets a zero pivot: that is what
lets many small components be eliminated together as one batch of object
arrays.

The components (:func:`scipy.sparse.csgraph.connected_components`) are ordered
by *level* -- 0 for those with no edge to another component, else one more
than the highest level they lead to -- so all components of a level depend
only on lower levels and are solved together: their edges to solved states are
folded into the right-hand side, then each batch of same-size components is
eliminated at once (Gauss-Jordan over ``(batch, k, k+1)`` object arrays of
:class:`gmpy2.mpq`). Components larger than :data:`BATCH_LIMIT` are solved one
by one by sparse state elimination.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from gmpy2 import mpq
from scipy.sparse import csgraph

from veribattery._types import BoolArray, CsrMatrix, IntArray
from veribattery._unique import distinct
from veribattery.explore.exact.rational import ObjectArray

__all__ = ["BATCH_LIMIT", "ExactSystem", "Prepared", "prepare", "restrict", "row_products", "solve"]

#: Components up to this size are eliminated in batches; larger ones one by one.
BATCH_LIMIT = 12

_ZERO = mpq(0)
_ONE = mpq(1)


@dataclass(frozen=True, slots=True)
class ExactSystem:
    """``A`` = the transition probabilities among the *m* unknowns, as coordinate lists."""

    size: int
    rows: IntArray
    columns: IntArray
    values: ObjectArray


def restrict(P: CsrMatrix, probabilities: ObjectArray, maybe: BoolArray) -> ExactSystem:
    """The entries of *P* between *maybe* states, renumbered ``0..m-1`` (rows sorted).

    :param P: the float CSR matrix (its structure).
    :param probabilities: exact value of each entry of *P*, in CSR data order.
    """
    idx = np.flatnonzero(maybe)
    local = np.full(P.shape[0], -1, dtype=np.int64)
    local[idx] = np.arange(idx.size)
    positions, rows = _row_entries(P.indptr, idx)
    columns = local[P.indices[positions]]
    keep = columns >= 0
    return ExactSystem(idx.size, rows[keep], columns[keep], probabilities[positions[keep]])


def row_products(P: CsrMatrix, probabilities: ObjectArray, rows: IntArray,
                 x: ObjectArray) -> ObjectArray:
    """``(P x)[rows]`` exactly."""
    positions, owner = _row_entries(P.indptr, rows)
    products = probabilities[positions] * x[P.indices[positions]]
    return _sums(owner, products, rows.size)


def _row_entries(indptr: IntArray, rows: IntArray) -> tuple[IntArray, IntArray]:
    """CSR positions of the entries of *rows*, and the index in *rows* of each."""
    starts = indptr[rows].astype(np.int64)
    lengths = indptr[rows + 1].astype(np.int64) - starts
    owner = np.repeat(np.arange(rows.size), lengths)
    offsets = np.arange(owner.size) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return np.repeat(starts, lengths) + offsets, owner


def _sums(owner: IntArray, values: ObjectArray, size: int) -> ObjectArray:
    """Per-row sums of *values* grouped by *owner* (sorted), exact zeros for empty rows."""
    result = np.full(size, _ZERO, dtype=object)
    if owner.size:
        starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
        result[owner[starts]] = np.add.reduceat(values, starts)
    return result


# ---------------------------------------------------------------------------
# Components and levels
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Order:
    """Unknowns renumbered so that each level, and each component in it, is contiguous."""

    position: IntArray  # new position of each unknown
    level_starts: IntArray  # positions where each level begins (plus the end)
    component: IntArray  # component of each position
    component_start: IntArray  # first position of each component (by component id)
    component_size: IntArray


def _order(system: ExactSystem) -> _Order:
    m = system.size
    graph = sp.csr_matrix(
        (np.ones(system.rows.size, dtype=np.int8), (system.rows, system.columns)), shape=(m, m)
    )
    count, labels = csgraph.connected_components(graph, directed=True, connection="strong")
    levels = _levels(count, labels[system.rows], labels[system.columns])
    order = np.lexsort((labels, levels[labels]))
    position = np.empty(m, dtype=np.int64)
    position[order] = np.arange(m)
    component = labels[order]
    sizes = np.bincount(labels, minlength=count)
    start = np.full(count, m, dtype=np.int64)
    np.minimum.at(start, component, np.arange(m))
    per_level = np.bincount(levels[component], minlength=int(levels.max(initial=-1)) + 1)
    level_starts = np.concatenate([[0], np.cumsum(per_level)])
    return _Order(position, level_starts, component, start, sizes)


def _levels(count: int, tails: IntArray, heads: IntArray) -> IntArray:
    """Longest-path distance of each component to a sink of the condensation (Kahn, peeled)."""
    cross = tails != heads
    pairs = distinct(tails[cross].astype(np.int64) * count + heads[cross])
    tail, head = pairs // count, pairs % count
    out_degree = np.bincount(tail, minlength=count)
    by_head = np.argsort(head, kind="stable")
    head_start = np.searchsorted(head[by_head], np.arange(count + 1))
    level = np.full(count, -1, dtype=np.int64)
    frontier = np.flatnonzero(out_degree == 0)
    depth = 0
    while frontier.size:
        level[frontier] = depth
        entries, _ = _row_entries(head_start, frontier)
        predecessors, times = np.unique(tail[by_head[entries]], return_counts=True)
        out_degree[predecessors] -= times
        frontier = predecessors[out_degree[predecessors] == 0]
        depth += 1
    return level


# ---------------------------------------------------------------------------
# Solving level by level
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Prepared:
    """A system's components and levels, with its entries renumbered and sorted by row."""

    size: int
    order: _Order
    rows: IntArray
    columns: IntArray
    values: ObjectArray
    entry_starts: IntArray  # first entry of each level's rows


def prepare(system: ExactSystem) -> Prepared:
    """Order *system*'s unknowns by level and component (reusable for many right-hand sides)."""
    order = _order(system)
    rows, columns = order.position[system.rows], order.position[system.columns]
    by_row = np.argsort(rows, kind="stable")
    rows, columns, values = rows[by_row], columns[by_row], system.values[by_row]
    entry_starts = np.searchsorted(rows, order.level_starts)
    return Prepared(system.size, order, rows, columns, values, entry_starts)


def solve(system: ExactSystem | Prepared, b: ObjectArray) -> ObjectArray:
    """The unique solution of ``x = A x + b`` (``I - A`` a nonsingular M-matrix).

    :param system: ``A`` among the *m* unknowns (see :func:`restrict`), or it prepared.
    :param b: right-hand side, one ``mpq`` per unknown.
    :return: ``x``, one ``mpq`` per unknown, in the unknowns' order.
    """
    if system.size == 0:
        return np.empty(0, dtype=object)
    ready = system if isinstance(system, Prepared) else prepare(system)
    order = ready.order
    rhs = np.empty(ready.size, dtype=object)
    rhs[order.position] = b
    x = np.empty(ready.size, dtype=object)
    bounds, starts = order.level_starts, ready.entry_starts
    for level in range(bounds.size - 1):
        e0, e1 = starts[level], starts[level + 1]
        _solve_level(order, int(bounds[level]), int(bounds[level + 1]), ready.rows[e0:e1],
                     ready.columns[e0:e1], ready.values[e0:e1], rhs, x)
    return np.asarray(x[order.position], dtype=object)


def _solve_level(
    order: _Order, lo: int, hi: int, rows: IntArray, columns: IntArray,
    values: ObjectArray, rhs: ObjectArray, x: ObjectArray,
) -> None:
    """Fold the solved neighbours into the right-hand side, then solve each component."""
    solved = columns < lo  # lower levels come first
    known = rhs[lo:hi] + _sums(rows[solved] - lo, values[solved] * x[columns[solved]], hi - lo)
    inner = ~solved
    rows, columns, values = rows[inner], columns[inner], values[inner]
    present = order.component[lo:hi]  # sorted: components are contiguous
    components = present[np.r_[True, present[1:] != present[:-1]]]
    sizes = order.component_size[components]
    for k in (1,) if sizes.max() == 1 else np.unique(sizes):
        batch = components[sizes == k]
        if k <= BATCH_LIMIT:
            _solve_batch(order, int(k), batch, lo, rows, columns, values, known, x)
        else:
            for single in batch:
                _solve_large(order, int(k), int(single), lo, rows, columns, values, known, x)


def _solve_batch(
    order: _Order, k: int, batch: IntArray, lo: int, rows: IntArray, columns: IntArray,
    values: ObjectArray, known: ObjectArray, x: ObjectArray,
) -> None:
    """Gauss-Jordan without pivoting on ``I - A_CC`` for every component *C* of *batch*."""
    starts = order.component_start[batch]
    if k == 1:
        alone = order.component_size[order.component[rows]] == 1
        _solve_single(starts, rows[alone], columns[alone], values[alone], known[starts - lo], x)
        return
    owner = np.searchsorted(batch, order.component[rows])  # batch is sorted
    mine = batch[np.minimum(owner, batch.size - 1)] == order.component[rows]
    base = starts[owner[mine]]
    M = np.full((batch.size, k, k + 1), _ZERO, dtype=object)
    diagonal = np.arange(k)
    M[:, diagonal, diagonal] = _ONE
    M[owner[mine], rows[mine] - base, columns[mine] - base] -= values[mine]
    members = (starts[:, None] + diagonal[None, :]).reshape(-1)
    M[:, :, k] = known[members - lo].reshape(batch.size, k)
    for i in range(k):
        M[:, i, :] = M[:, i, :] / M[:, i, i][:, None]
        others = np.delete(diagonal, i)
        M[:, others, :] -= M[:, others, i][:, :, None] * M[:, i, None, :]
    x[members] = M[:, :, k].reshape(-1)


def _solve_single(
    states: IntArray, rows: IntArray, columns: IntArray, values: ObjectArray,
    known: ObjectArray, x: ObjectArray,
) -> None:
    """One-state components: ``x_s = known_s / (1 - a_ss)``, dividing only where a loop is."""
    x[states] = known
    loops = rows == columns  # the entries given are those of one-state components
    if loops.any():
        at = rows[loops]
        x[at] = x[at] / (_ONE - values[loops])


def _solve_large(
    order: _Order, k: int, component: int, lo: int, rows: IntArray, columns: IntArray,
    values: ObjectArray, known: ObjectArray, x: ObjectArray,
) -> None:
    """One large component by sparse state elimination (a Python loop over its entries).

    Eliminating state *s* from ``x = A x + b`` first divides its row by
    ``1 - a_ss`` (positive: the component leaks) and then substitutes it into
    every row that refers to it; rows stay sparse when states are eliminated
    in increasing order of (in-degree x out-degree), as a chain's are.
    """
    start = int(order.component_start[component])
    mine = (rows >= start) & (rows < start + k)
    equations: list[dict[int, mpq]] = [{} for _ in range(k)]
    users: list[set[int]] = [set() for _ in range(k)]
    for r, c, v in zip(rows[mine] - start, columns[mine] - start, values[mine], strict=True):
        equations[r][c] = v
        users[c].add(r)
    constant = list(known[start - lo : start - lo + k])
    eliminated = _eliminate(equations, users, constant)
    solution: list[mpq] = [_ZERO] * k
    for s in reversed(eliminated):
        solution[s] = constant[s] + sum(
            (v * solution[j] for j, v in equations[s].items()), _ZERO
        )
    x[start : start + k] = solution


def _eliminate(
    equations: list[dict[int, mpq]], users: list[set[int]], constant: list[mpq]
) -> list[int]:
    """Eliminate every state in turn; return the order (rows then name later states only)."""
    k = len(equations)
    cost = [len(users[s]) * len(equations[s]) for s in range(k)]
    order = sorted(range(k), key=cost.__getitem__)
    for s in order:
        row = equations[s]
        loop = row.pop(s, None)
        users[s].discard(s)
        if loop is not None:
            scale = _ONE / (_ONE - loop)
            for j in row:
                row[j] *= scale
            constant[s] *= scale
        for i in users[s]:
            weight = equations[i].pop(s)
            target = equations[i]
            for j, v in row.items():
                target[j] = target.get(j, _ZERO) + weight * v
                users[j].add(i)
            constant[i] += weight * constant[s]
        for j in row:
            users[j].discard(s)
        users[s] = set()
    return order
