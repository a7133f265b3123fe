"""Solving ``A x = b`` (``A = I - P_mm``) component by component in topological order.

The strongly connected components of *A*'s graph, ordered so that every
component comes after the components it leads to (successors first), make the
permuted matrix block lower triangular. The system is then solved one
*segment* at a time, each once everything it reads is known:

* ``"substitution"``: a maximal run of *trivial* components (one state each,
  perhaps with a self-loop) is a triangular system. It is solved by one sparse
  forward substitution in C (SuperLU's triangular solve, the routine
  :func:`scipy.sparse.linalg.spsolve_triangular` calls, on arrays made once:
  :func:`~veribattery.checker.linalg.compact_lu.unit_lower_solve`): linear in the run's
  transitions whatever its depth, with no Python loop per state or per level.
  (A substitution level by level -- every state whose successors are known at
  once, vectorised in numpy -- costs a Python iteration per level, and a chain
  of 10^6 states has 10^6 levels.) Where only self-loops stay on a state the
  answer is ``x_i = (b_i + sum_j P_ij x_j) / (1 - P_ii)``, the leaving
  probability read from *A*'s diagonal exactly as the certificate reads it.
* ``"blocks"``: a maximal run of small components (at most
  :data:`SMALL_LIMIT` states, some of more than one state): sparse LU in the
  natural (topological) order with diagonal pivots, so the fill stays inside
  each component -- every component solved directly, in one call into C.
* ``"component"``: every larger component alone, by the solver that
  *component_solver* makes for its diagonal block (LU, multigrid-preconditioned
  Krylov, ...: whatever converges for it; :func:`direct_component` by default).

The result is an approximate solution like any other solver's: the caller's
certificate (``certify.quick_certificate`` / ``certify_fixpoint``) decides
whether it is good enough and bounds its error rigorously, and this solver
doubles as the approximate inverse those certificates use for their margins.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.sparse import linalg as spla

from veribattery._types import FloatArray, IntArray
from veribattery._unique import distinct
from veribattery.checker.linalg.compact_lu import compact_solve, unit_lower_solve
from veribattery.errors import CheckError

__all__ = [
    "SMALL_LIMIT",
    "ComponentSolver",
    "Condensation",
    "Inverse",
    "Progress",
    "Segment",
    "TopologicalSolver",
    "condensation",
    "direct_component",
    "segments",
]

#: Components of at most this many states are solved together with their
#: neighbours in runs (one LU call for the whole run).
SMALL_LIMIT = 64

#: Applies an approximate inverse of a component's diagonal block to a vector.
Inverse = Callable[[FloatArray], FloatArray]
#: Makes the solver of one large component from its diagonal block (CSR, float64);
#: None when it cannot (the whole solve then fails with :class:`CheckError`).
ComponentSolver = Callable[[sp.csr_matrix], Inverse | None]
#: Told ``(states solved, states in total)`` after each segment of a solve.
Progress = Callable[[int, int], None]


@dataclass(frozen=True, slots=True)
class Condensation:
    """The states in a topological order of their SCCs (successors first).

    :param order: ``order[k]`` is the state at position *k*.
    :param starts: the first position of every component, then the number of states.
    """

    order: IntArray
    starts: IntArray

    @property
    def sizes(self) -> IntArray:
        """The number of states of each component, in order."""
        return np.diff(self.starts)

    @property
    def count(self) -> int:
        """The number of components."""
        return int(self.starts.size - 1)


def condensation(A: sp.csr_matrix) -> Condensation:
    """The SCCs of *A*'s graph (its stored entries) in topological order, successors first.

    scipy's labelling (Pearce's algorithm) numbers the components in a topological
    order; which of the two directions is checked against every edge between
    components, and an order is computed from the condensed graph should neither hold.
    """
    count, labels = csgraph.connected_components(A, directed=True, connection="strong")
    labels = labels.astype(np.int64, copy=False)
    src = np.repeat(labels, np.diff(A.indptr))
    dst = labels[A.indices]
    across = src != dst
    src, dst = src[across], dst[across]
    if np.all(dst < src):
        key = labels
    elif np.all(dst > src):
        key = (count - 1) - labels
    else:  # pragma: no cover -- scipy's labels have always been topological
        key = _topological_labels(count, labels, src, dst)
    order = np.argsort(key, kind="stable").astype(np.int64)
    sizes = np.bincount(key, minlength=count)
    starts = np.zeros(count + 1, dtype=np.int64)
    np.cumsum(sizes, out=starts[1:])
    return Condensation(order, starts)


def _topological_labels(count: int, labels: IntArray, src: IntArray,
                        dst: IntArray) -> IntArray:
    """Component numbers in a topological order of the condensed graph (successors
    first), by peeling the components whose successors are all numbered, a level at
    a time (vectorised per level)."""
    graph = sp.csr_matrix((np.ones(src.size, dtype=np.int8), (src, dst)), shape=(count, count))
    graph.sum_duplicates()
    reverse = graph.T.tocsr()
    pending = np.diff(graph.indptr).astype(np.int64)  # successors not yet numbered
    rank = np.empty(count, dtype=np.int64)
    frontier = np.flatnonzero(pending == 0)
    done = 0
    while frontier.size:
        rank[frontier] = np.arange(done, done + frontier.size)
        done += frontier.size
        predecessors = reverse.indices[np.concatenate(
            [np.arange(reverse.indptr[c], reverse.indptr[c + 1]) for c in frontier])]
        np.subtract.at(pending, predecessors, 1)
        candidates = distinct(predecessors)
        frontier = candidates[pending[candidates] == 0]
    if done != count:
        raise CheckError("the condensation of a linear system has a cycle")
    return rank[labels]


@dataclass(frozen=True, slots=True)
class Segment:
    """Positions ``[lo, hi)`` of the topological order solved together, and how."""

    lo: int
    hi: int
    method: str


def segments(found: Condensation, small: int = SMALL_LIMIT) -> tuple[Segment, ...]:
    """The segments of *found*: each component of more than *small* states alone
    (``"component"``), the others in maximal runs (``"substitution"`` when every
    component of the run is a single state, else ``"blocks"``)."""
    sizes = found.sizes
    large = sizes > small
    # Cut before and after every large component and where the run changes kind.
    kind = np.where(large, 2, np.where(sizes > 1, 1, 0))
    boundary = np.flatnonzero(large[1:] | large[:-1] | (kind[1:] != kind[:-1])) + 1
    cuts = np.concatenate([[0], boundary, [found.count]])
    result = []
    for first, last in itertools.pairwise(cuts.tolist()):
        lo, hi = int(found.starts[first]), int(found.starts[last])
        method = ("component" if large[first]
                  else "blocks" if kind[first] == 1 else "substitution")
        result.append(Segment(lo, hi, method))
    return _merged(result, small)


def _merged(parts: list[Segment], small: int) -> tuple[Segment, ...]:
    """Short substitution runs (fewer than *small* states) joined to an adjacent run of
    small components (the LU of a run does not mind single states), so that a model
    alternating single states and small cycles is not solved a few states per segment."""
    merged: list[Segment] = []
    for part in parts:
        last = merged[-1] if merged else None
        if last is not None and _joinable(last, part, small):
            merged[-1] = Segment(last.lo, part.hi, "blocks")
        else:
            merged.append(part)
    return tuple(merged)


def _joinable(first: Segment, second: Segment, small: int) -> bool:
    kinds = {first.method, second.method}
    if kinds == {"blocks"}:
        return True
    if kinds != {"blocks", "substitution"}:
        return False
    run = first if first.method == "substitution" else second
    return run.hi - run.lo < small


def direct_component(block: sp.csr_matrix) -> Inverse | None:
    """Sparse LU of one component (fill-reducing order, diagonal pivots: *block* is a
    nonsingular M-matrix), or None when the factorisation fails."""
    return superlu(block, "MMD_AT_PLUS_A")


def superlu(block: sp.spmatrix, order: str) -> Inverse | None:
    """SuperLU with column order *order* and diagonal pivots (None if it fails).

    "NATURAL" keeps a topologically ordered run's fill-in inside each component;
    "MMD_AT_PLUS_A" (minimum degree on ``A + A^T``) limits it in one large component.
    """
    try:
        lu = spla.splu(sp.csc_matrix(block), permc_spec=order, diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except (RuntimeError, MemoryError):
        return None
    return compact_solve(lu)


@dataclass(frozen=True, slots=True)
class _Part:
    """One segment ready to solve: its coupling to earlier positions and its solver."""

    segment: Segment
    coupling: sp.csr_matrix | None
    solve: Inverse


class TopologicalSolver:
    """An approximate inverse of *A* that solves it SCC by SCC in topological order.

    Prepared once (condensation, permutation, per-segment solvers), applied to any
    number of right-hand sides.

    :param A: ``I - P_mm`` in float64 (CSR): a nonsingular M-matrix, diagonal > 0.
    :param component_solver: makes the solver of each large component.
    :param small: the largest component solved in a run with its neighbours.
    :raises CheckError: when a diagonal entry is not positive or a component's
        solver cannot be made.
    """

    def __init__(self, A: sp.csr_matrix, component_solver: ComponentSolver = direct_component,
                 small: int = SMALL_LIMIT) -> None:
        found = condensation(A)
        self._order = found.order
        self._n = int(A.shape[0])
        permuted = _permuted(A, found.order)
        self._parts = tuple(_prepare(permuted, segment, component_solver)
                            for segment in segments(found, small))

    @property
    def methods(self) -> dict[str, int]:
        """The number of states solved by each method."""
        counts: dict[str, int] = {}
        for part in self._parts:
            size = part.segment.hi - part.segment.lo
            counts[part.segment.method] = counts.get(part.segment.method, 0) + size
        return counts

    @property
    def segments(self) -> tuple[Segment, ...]:
        """The segments, in the order they are solved."""
        return tuple(part.segment for part in self._parts)

    def __call__(self, b: FloatArray) -> FloatArray:
        return self.solve(b)

    def solve(self, b: FloatArray, progress: Progress | None = None) -> FloatArray:
        """``A^-1 b`` approximately (each segment as accurately as its method gives).

        :param progress: told the states solved so far after each segment.
        """
        permuted_b = np.asarray(b, dtype=np.float64)[self._order]
        y = np.empty(self._n, dtype=np.float64)
        for part in self._parts:
            lo, hi = part.segment.lo, part.segment.hi
            rhs = permuted_b[lo:hi]
            if part.coupling is not None:
                rhs = rhs - part.coupling @ y[:lo]
            y[lo:hi] = part.solve(np.ascontiguousarray(rhs))
            if progress is not None:
                progress(hi, self._n)
        x = np.empty_like(y)
        x[self._order] = y
        return x


def _permuted(A: sp.csr_matrix, order: IntArray) -> sp.csr_matrix:
    """``A[order][:, order]``: block lower triangular (successors first)."""
    position = np.empty_like(order)
    position[order] = np.arange(order.size, dtype=order.dtype)
    rows = sp.csr_matrix(A[order])
    # (the positions narrowed first: no temporary of the entries' width in int64)
    rows.indices = position.astype(rows.indices.dtype)[rows.indices]
    rows.has_sorted_indices = False
    rows.sort_indices()
    return rows


def _prepare(permuted: sp.csr_matrix, segment: Segment,
             component_solver: ComponentSolver) -> _Part:
    """The segment's coupling rows and its diagonal block's solver."""
    lo, hi = segment.lo, segment.hi
    # (one slice each, not the segment's rows and then their columns: a copy fewer)
    coupling = sp.csr_matrix(permuted[lo:hi, :lo]) if lo else None
    if coupling is not None and coupling.nnz == 0:
        coupling = None
    solve: Inverse | None
    if segment.method == "substitution":
        # The CSC made from the block, which dies with this statement: the CSR and CSC
        # copies of a large run never outlive each other's making.
        solve = _substitution(_diagonal_block(permuted, lo, hi).tocsc())
    else:
        block = _diagonal_block(permuted, lo, hi)
        _check_diagonal(block.diagonal())
        solve = (superlu(block, "NATURAL") if segment.method == "blocks"
                 else component_solver(block))
    if solve is None:
        raise CheckError(f"no solver for a component of {hi - lo} states")
    return _Part(segment, coupling, solve)


def _diagonal_block(permuted: sp.csr_matrix, lo: int, hi: int) -> sp.csr_matrix:
    """``permuted[lo:hi, lo:hi]``: *permuted* itself where that is all of it (a system
    solved as one segment then has no second copy of its matrix)."""
    if lo == 0 and hi == permuted.shape[0]:
        return permuted
    return sp.csr_matrix(permuted[lo:hi, lo:hi])


def _check_diagonal(diagonal: FloatArray) -> None:
    if not np.all(diagonal > 0):
        raise CheckError("a state of a linear system has no positive leaving probability")


def _substitution(lower: sp.csc_matrix) -> Inverse:
    """Forward substitution with the lower-triangular CSC *lower* (a run of single-state
    components in topological order), by columns scaled to a unit diagonal."""
    # (each diagonal entry is its column's, summed in the order its row stored it)
    diagonal: FloatArray = lower.diagonal()
    _check_diagonal(diagonal)
    scale = 1.0 / diagonal
    del diagonal
    lower.sort_indices()
    first = lower.indptr[:-1]
    # Lower triangular with the diagonal stored. Every column stores its diagonal (it is
    # positive) and its rows ascend (sorted indices), so where its first row is its own,
    # none lies above the diagonal: that test alone says the block is lower triangular.
    if np.any(lower.indices[first] != np.arange(lower.shape[1])):
        raise CheckError("a run of single-state components is not triangular")
    _scale_columns(lower, scale)
    lower.data[first] = 1.0  # exactly, as the solve reads it
    triangular = unit_lower_solve(lower)

    def solve(b: FloatArray) -> FloatArray:
        if triangular is not None:
            y = triangular(b)
        else:  # (overwrite_A: it sets the diagonal to 1, where it is already)
            y = spla.spsolve_triangular(lower, b, lower=True, unit_diagonal=True,
                                        overwrite_A=True, overwrite_b=True)
        with np.errstate(over="ignore"):  # beyond the doubles: inf, rejected or certified
            return np.asarray(y, dtype=np.float64) * scale

    return solve


#: Columns scaled at a time by :func:`_scale_columns`.
SCALE_CHUNK = 1 << 16


def _scale_columns(matrix: sp.csc_matrix, scale: FloatArray) -> None:
    """Every column of *matrix* times its *scale*, in place: the same products as with
    the factors repeated for all entries at once, whose vector as long as the entries
    would outlive this call's peak (a chunk of columns at a time)."""
    indptr = matrix.indptr
    for lo in range(0, scale.size, SCALE_CHUNK):
        hi = min(lo + SCALE_CHUNK, scale.size)
        matrix.data[indptr[lo]:indptr[hi]] *= np.repeat(scale[lo:hi],
                                                         np.diff(indptr[lo:hi + 1]))
