"""Restriction of a transition matrix to the unknown states: ``I - P_mm`` and its rows.

The matrix is built in float64 with an extended-precision residue of its diagonal
(the leaving probabilities), and the index work of a restriction is kept per sparsity
pattern in :class:`SolverPlans` for later matrices of the same pattern.
"""

from __future__ import annotations

import hashlib
import weakref
from collections import OrderedDict
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from veribattery._sparse import csr_sharing
from veribattery._types import BoolArray, CsrMatrix, FloatArray

if TYPE_CHECKING:
    from veribattery.checker.linalg.triangular import _TriangularPlan


ExtArray = npt.NDArray[np.longdouble]


class SolverPlans:
    """The index work of restricted systems and substitutions, kept for later matrices of
    the same sparsity pattern (a structure-reusing sweep: same states and transitions,
    other probabilities), so that only their values are gathered anew.

    A plan is made the second time its pattern is seen: a single check never pays for
    one. Held by a :class:`~veribattery.checker.workspace.Workspace`; every bound is
    small (a few patterns each).
    """

    def __init__(self) -> None:
        #: Digests of index arrays by the arrays' identity (:func:`index_digest`).
        self.digests: OrderedDict[tuple[int, int], tuple[
            weakref.ref[npt.NDArray[np.integer]], weakref.ref[npt.NDArray[np.integer]],
            bytes]] = OrderedDict()
        #: Restriction plans by (pattern, unknown states) digest (None: seen once).
        self.restrictions: OrderedDict[bytes, _RestrictionPlan | None] = OrderedDict()
        #: Substitution plans by pattern digest (None: the pattern has a cycle).
        self.triangular: OrderedDict[bytes, _TriangularPlan | None] = OrderedDict()
        #: Patterns whose substitution plan was made once and not kept: a plan (~40 MB
        #: at 1.4M states) is kept only for a pattern seen again, as restrictions are.
        self.triangular_seen: OrderedDict[bytes, None] = OrderedDict()
        #: The modes ("N", "T") in which the private triangular solve has been seen to
        #: solve ``L y = 1`` / ``L^T y = 1`` (see :func:`_substitution`).
        self.private_modes: set[str] = set()

    @property
    def empty(self) -> bool:
        """Whether nothing is kept yet."""
        return not (self.digests or self.restrictions or self.triangular
                    or self.triangular_seen or self.private_modes)


def restricted_matrix(P: CsrMatrix, maybe: BoolArray, plans: SolverPlans | None = None
                      ) -> tuple[sp.csr_matrix, CsrMatrix]:
    """``I - P[maybe, maybe]`` in extended precision, and the rows ``P[maybe, :]``.

    The diagonal is the probability of leaving each state, summed from the
    off-diagonal entries, rather than ``1 - P_ii``: that cancels
    catastrophically for self-loops close to 1, and rows that do not sum to
    exactly 1 in float64 would leak or gain mass. (Kernels use
    :func:`restricted_parts`, which stores the same matrix in float64.)

    :param plans: where restriction plans are kept (see :func:`restricted_parts`).
    """
    A64, residue, rows = restricted_parts(P, maybe, plans)
    A = A64.astype(np.longdouble) + residue
    return sp.csr_matrix(A), rows


def restricted_parts(P: CsrMatrix, maybe: BoolArray, plans: SolverPlans | None = None
                     ) -> tuple[sp.csr_matrix, sp.csr_matrix, CsrMatrix]:
    """:func:`restricted_matrix` as ``A64 + residue``: the float64 matrix (diagonal
    rounded to nearest) and the extended-precision rounding residue of the diagonal.

    The off-diagonal entries are stored probabilities, exact in float64, so only
    the diagonal needs more: 8 bytes per state instead of 16 per nonzero. Index
    work depends only on *P*'s pattern and *maybe*, so *plans* keeps it by them
    (:class:`_RestrictionPlan`, made the second time they are seen); the values are
    then gathered. Without *plans* nothing is kept (the same arrays, bit for bit).
    """
    plan = None if plans is None else _restriction_plan(P, maybe, plans)
    if plan is not None:
        found = plan.apply(P)
        if found is not None:
            return found
    return _restricted_parts(P, maybe)


def unplanned_parts(P: CsrMatrix, maybe: BoolArray
                    ) -> tuple[sp.csr_matrix, sp.csr_matrix, CsrMatrix]:
    """:func:`restricted_parts` without consulting or making a restriction plan (the same
    arrays bit for bit), for making a released system matrix again."""
    return _restricted_parts(P, maybe)


def _restricted_parts(P: CsrMatrix, maybe: BoolArray
                      ) -> tuple[sp.csr_matrix, sp.csr_matrix, CsrMatrix]:
    idx = np.flatnonzero(maybe)
    rows = sp.csr_matrix(P[idx])
    n = idx.size
    # Built straight from the rows' arrays (column renumbering, diagonal slot per
    # row), not by sparse column slicing and subtraction: each of those allocates
    # a whole new matrix, several times the final one at 10^6 states.
    index = np.int32 if max(P.shape[1], rows.nnz + n) < 2**31 else np.int64
    position = np.full(P.shape[1], -1, dtype=index)
    position[idx] = np.arange(n, dtype=index)
    row_of = np.repeat(np.arange(n, dtype=index), np.diff(rows.indptr))
    column = position[rows.indices]
    del position, idx
    moves = column != row_of
    if rows.has_sorted_indices:
        # Renumbering keeps each row's order (position is increasing): the rows here
        # are sorted too, and the diagonal is slotted into them (no sort, no scatter).
        A64, leave, leave64 = _sorted_system(rows, row_of, column, moves, index)
    else:
        leave = _row_sums(row_of[moves], rows.data[moves], n)
        leave64 = leave.astype(np.float64)
        keep = moves & (column >= 0) & (rows.data != 0)
        del moves
        A64 = _with_diagonal(row_of[keep], column[keep], -rows.data[keep], leave64)
    del row_of, column  # before the residue: these are per entry
    leave -= leave64  # the residue, in place (leave64 widens exactly)
    return A64, _diagonal_residue(leave), rows


def _sorted_system(rows: sp.csr_matrix, row_of: npt.NDArray[Any],
                   column: npt.NDArray[Any], moves: BoolArray, index: type[np.integer[Any]]
                   ) -> tuple[sp.csr_matrix, ExtArray, FloatArray]:
    """``A64`` of rows in column order, with the leaving probabilities (extended, and
    rounded to float64): the same arrays as :func:`_with_diagonal` and :func:`_row_sums`
    give, in a few whole-array passes per entry.

    A row's leaving probability is the sum of its movers, in extended precision and
    over the same segments as :func:`_row_sums` (numpy's reductions pair the terms
    by position: zeros in place of the other entries would change the last bits).
    Each row's kept entries are then laid out with its diagonal between those of
    smaller and of larger column.
    """
    n = rows.shape[0]
    nonempty = np.flatnonzero(np.diff(rows.indptr))
    firsts = rows.indptr[nonempty]
    leave = _mover_sums(rows.data[moves], nonempty,
                        np.add.reduceat(moves, firsts, dtype=np.int64), n)
    leave64 = leave.astype(np.float64)
    keep = moves & (column >= 0) & (rows.data != 0)
    kept = np.zeros(n, dtype=np.int64)
    below = np.zeros(n, dtype=np.int64)
    kept[nonempty] = np.add.reduceat(keep, firsts, dtype=np.int64)
    below[nonempty] = np.add.reduceat(keep & (column < row_of), firsts, dtype=np.int64)
    indptr = np.zeros(n + 1, dtype=index)
    np.cumsum(kept + 1, out=indptr[1:])
    diagonal_at = indptr[:-1] + below
    off_diagonal = np.ones(int(indptr[-1]), dtype=bool)
    off_diagonal[diagonal_at] = False
    indices = np.empty(int(indptr[-1]), dtype=index)
    values = np.empty(int(indptr[-1]), dtype=np.float64)
    indices[off_diagonal] = column[keep]
    values[off_diagonal] = np.negative(rows.data[keep])
    indices[diagonal_at] = np.arange(n, dtype=index)
    values[diagonal_at] = leave64
    matrix = sp.csr_matrix((values, indices, indptr), shape=(n, n))
    matrix.has_sorted_indices = True
    matrix.eliminate_zeros()
    return matrix, leave, leave64


#: Index-array digests kept by a :class:`SolverPlans` (see :func:`index_digest`).
INDEX_DIGESTS_KEPT = 8


def index_digest(indptr: npt.NDArray[np.integer], indices: npt.NDArray[np.integer],
                 plans: SolverPlans | None = None) -> bytes:
    """A digest of a sparse matrix's index arrays, memoised in *plans* by the arrays'
    identity.

    Matrices of a structure-reusing sweep share their index arrays (the re-evaluated
    transition matrix takes the base's, :func:`veribattery.explore.reuse.reevaluate`;
    a restriction plan's ``A64`` takes the plan's), so each point's pattern lookups
    (pre-pass memo, restriction plan, triangular plan) hash no index array again.
    Index arrays are never modified in place once a matrix is built (as the memos
    here already require).
    """
    key = (id(indptr), id(indices))
    kept = None if plans is None else plans.digests
    found = None if kept is None else kept.get(key)
    if found is not None and found[0]() is indptr and found[1]() is indices:
        assert kept is not None
        kept.move_to_end(key)
        return found[2]
    digest = hashlib.blake2b(digest_size=20)
    digest.update(np.ascontiguousarray(indptr).data)
    digest.update(np.ascontiguousarray(indices).data)
    value = digest.digest()
    if kept is not None:
        kept[key] = (weakref.ref(indptr), weakref.ref(indices), value)
        while len(kept) > INDEX_DIGESTS_KEPT:
            kept.popitem(last=False)
    return value


@dataclass(frozen=True, slots=True)
class _RestrictionPlan:
    """The index work of :func:`restricted_parts` for one pattern of *P* and *maybe*.

    :param gather: positions in ``P.data`` of the entries of ``P[maybe]``, in order.
    :param movers: positions, among those, of the entries that leave their row's state.
    :param mover_rows: the row of each mover.
    :param source: per entry of ``A64``: ``-1 - i`` for row *i*'s diagonal (the
        leaving probability), else the position in the gathered data (negated).
    """

    shape: tuple[int, int]
    gather: npt.NDArray[np.int64]
    rows_indices: npt.NDArray[np.int32]
    rows_indptr: npt.NDArray[np.int64]
    movers: npt.NDArray[np.int64]
    mover_rows: npt.NDArray[np.int64]
    source: npt.NDArray[np.int64]
    a_indices: npt.NDArray[np.int32]
    a_indptr: npt.NDArray[np.int32]
    #: The rows with movers and where each one's movers start (for one ``reduceat``).
    sum_rows: npt.NDArray[np.intp]
    sum_starts: npt.NDArray[np.intp]
    #: Per entry of ``A64``, its position in ``[-gathered data, leaving probabilities]``.
    a_take: npt.NDArray[np.intp]

    def apply(self, P: CsrMatrix) -> tuple[sp.csr_matrix, sp.csr_matrix, CsrMatrix] | None:
        """The parts for *P* (of the plan's pattern), equal bit for bit to a fresh
        computation; None when a leaving probability is 0 (the plan assumed not)."""
        m = self.shape[0]
        data = np.asarray(P.data[self.gather], dtype=np.float64)
        rows = csr_sharing(data, self.rows_indices, self.rows_indptr, (m, P.shape[1]))
        leave = self._leaving(data)
        leave64 = leave.astype(np.float64)
        if not np.all(leave64 != 0):
            return None
        a_data = np.take(np.concatenate([np.negative(data), leave64]), self.a_take)
        A64 = csr_sharing(a_data, self.a_indices, self.a_indptr, self.shape)
        return A64, _diagonal_residue(leave - leave64.astype(np.longdouble)), rows

    def _leaving(self, data: FloatArray) -> ExtArray:
        """:func:`_row_sums` of the movers: the same segments summed in the same order
        (one ``reduceat`` over all of them when they fit in one block)."""
        m = self.shape[0]
        if self.movers.size > _SUM_BLOCK or not self.movers.size:
            return _row_sums(self.mover_rows, data[self.movers], m)
        leave = np.zeros(m, dtype=np.longdouble)
        moving = np.take(data, self.movers).astype(np.longdouble)
        leave[self.sum_rows] = np.add.reduceat(moving, self.sum_starts)
        return leave


#: Restriction plans a :class:`SolverPlans` keeps: the last few (pattern, unknown
#: states) pairs (None: seen once).
RESTRICTIONS_KEPT = 8


def _restriction_plan(P: CsrMatrix, maybe: BoolArray, plans: SolverPlans
                      ) -> _RestrictionPlan | None:
    """The plan of *P*'s pattern (positions and positive entries) and *maybe* kept in
    *plans*, made the second time they are seen (None the first time)."""
    if not P.has_canonical_format:
        return None
    digest = hashlib.blake2b(digest_size=20)
    digest.update(np.asarray(P.shape, dtype=np.int64).tobytes())
    digest.update(index_digest(P.indptr, P.indices, plans))
    digest.update(np.packbits(P.data != 0).data)
    digest.update(np.packbits(maybe).data)
    key = digest.digest()
    kept = plans.restrictions
    plan = None
    if key in kept:  # seen before: a sweep re-uses the pattern, worth a plan
        kept.move_to_end(key)
        plan = kept[key] or _new_restriction(P, maybe)
    # A pattern seen once is only remembered (a single check never pays for a plan).
    kept[key] = plan
    while len(kept) > RESTRICTIONS_KEPT:
        kept.popitem(last=False)
    return plan


def _new_restriction(P: CsrMatrix, maybe: BoolArray) -> _RestrictionPlan | None:
    """Run :func:`_restricted_parts` once on tags instead of values to learn where
    every entry goes: a stored value ``v`` is tagged ``k + 1`` (its gathered
    position), a leaving probability ``i + 1`` (its row), so that each entry of
    ``A64`` (``leave`` on the diagonal, ``-v`` off it) names its source."""
    idx = np.flatnonzero(maybe)
    lengths = np.diff(P.indptr)[idx]
    starts = np.asarray(P.indptr[idx], dtype=np.int64)
    offsets = np.repeat(starts - (np.cumsum(lengths) - lengths), lengths)
    gather = offsets + np.arange(int(lengths.sum()), dtype=np.int64)
    tags = np.where(P.data[gather] != 0, np.arange(1, gather.size + 1, dtype=np.float64), 0.0)
    rows = sp.csr_matrix((tags, P.indices[gather],
                          np.concatenate([[0], np.cumsum(lengths)])), shape=(idx.size, P.shape[1]))
    row_of = np.repeat(np.arange(idx.size), lengths)
    moves = rows.indices != idx[row_of]
    inner = sp.csr_matrix(rows[:, idx])
    off = sp.csr_matrix(inner - sp.diags(inner.diagonal(), format="csr"))
    off.eliminate_zeros()
    tagged = sp.csr_matrix(sp.diags(np.arange(1, idx.size + 1, dtype=np.float64),
                                    format="csr") - off)
    tagged.sort_indices()
    # On the diagonal: i + 1 -> -1 - i; off it: -(k + 1) -> k.
    source = np.where(tagged.data > 0, -tagged.data, -tagged.data - 1).astype(np.int64)
    mover_rows = row_of[moves]
    counts = np.bincount(mover_rows, minlength=idx.size)
    sum_rows = np.flatnonzero(counts)
    sum_starts = (np.cumsum(counts) - counts)[sum_rows]
    a_take = np.where(source < 0, gather.size + (-1 - source), source).astype(np.intp)
    return _RestrictionPlan((idx.size, idx.size), gather, rows.indices.copy(),
                            rows.indptr.astype(np.int64), np.flatnonzero(moves),
                            mover_rows, source, tagged.indices.copy(), tagged.indptr.copy(),
                            sum_rows.astype(np.intp), sum_starts.astype(np.intp), a_take)


def _with_diagonal(row: npt.NDArray[np.integer], col: npt.NDArray[np.integer],
                   data: FloatArray, diagonal: FloatArray) -> sp.csr_matrix:
    """The CSR matrix of the row-sorted entries *(row, col, data)* plus *diagonal*
    (zeros not stored), indices sorted in place."""
    n = diagonal.size
    counts = np.bincount(row, minlength=n) + 1
    indptr = np.zeros(n + 1, dtype=col.dtype)
    np.cumsum(counts, out=indptr[1:])
    # Entry k of row r goes to k + r (one diagonal slot at the end of each earlier row).
    slots = np.arange(row.size, dtype=col.dtype) + row
    indices = np.empty(indptr[-1], dtype=col.dtype)
    values = np.empty(indptr[-1], dtype=np.float64)
    indices[slots], values[slots] = col, data
    indices[indptr[1:] - 1] = np.arange(n, dtype=col.dtype)
    values[indptr[1:] - 1] = diagonal
    matrix = sp.csr_matrix((values, indices, indptr), shape=(n, n))
    matrix.sort_indices()
    matrix.eliminate_zeros()
    return matrix


def _mover_sums(movers: FloatArray, rows: npt.NDArray[np.intp], counts: npt.NDArray[np.int64],
                n: int) -> ExtArray:
    """Per row, the sum of its *counts* consecutive entries of *movers* (the rows
    *rows*, in order), in extended precision: :func:`_row_sums`' segments and sums."""
    sums = np.zeros(n, dtype=np.longdouble)
    present = counts > 0
    starts = np.cumsum(counts) - counts
    sums[rows[present]] = np.add.reduceat(movers, starts[present], dtype=np.longdouble)
    return sums


def _diagonal_residue(residue: ExtArray) -> sp.csr_matrix:
    """The diagonal matrix of *residue*, its zeros not stored."""
    n = residue.size
    present = residue != 0
    # CSR straight away (one entry per row at most, on the diagonal; no COO copies).
    indptr = np.zeros(n + 1, dtype=np.int32 if n < 2**31 - 1 else np.int64)
    np.cumsum(present, out=indptr[1:])
    where = np.flatnonzero(present).astype(indptr.dtype)
    return sp.csr_matrix((residue[where], where, indptr), shape=(n, n), dtype=np.longdouble)


#: Entries per block of an extended-precision reduction (bounds its 16-byte copy).
_SUM_BLOCK = 1 << 20


def _row_sums(row_of: npt.NDArray[np.integer], data: FloatArray, n: int) -> ExtArray:
    """Per-row sums of sorted (row, value) pairs, in extended precision.

    The values are widened a block of whole rows at a time; the sums are those
    of one ``np.add.reduceat`` over all of them (the same segments, same order).
    """
    counts = np.bincount(row_of, minlength=n)
    sums = np.zeros(n, dtype=np.longdouble)
    ends = np.cumsum(counts)
    present = np.flatnonzero(counts)
    lo = 0
    while lo < present.size:
        # Whole rows, about _SUM_BLOCK entries (at least one row).
        first = ends[present[lo]] - counts[present[lo]]
        hi = max(lo + 1, int(np.searchsorted(ends[present], first + _SUM_BLOCK, "right")))
        chosen = present[lo:hi]
        stop = ends[chosen[-1]]
        block = data[first:stop].astype(np.longdouble)
        sums[chosen] = np.add.reduceat(block, ends[chosen] - counts[chosen] - first)
        lo = hi
    return sums
