"""Sparse linear systems ``(I - P_mm) x = b`` of the unbounded kernels, and their stopping rule.

The systems are nonsingular M-matrices (the qualitative pre-pass removed every
state that cannot leave the restricted set), but on long chains they are badly
conditioned: a symmetric random walk over n states has condition number ~n².
A plain LU solve there loses digits (1e-6 relative error at n = 10⁶), so:

1. **Direct.** A substitution (acyclic systems) or the SCC-wise solve of
   :mod:`~veribattery.checker.scc` (LU per segment, or preconditioned Krylov
   inside components too large to factorise), on the float64 matrix; then
   *mixed-precision iterative refinement* computes each residual ``b - A x``
   in extended precision (``numpy.longdouble``, 64-bit mantissa on x86-64;
   elsewhere it may be float64 and refinement only tightens the backward
   error) and corrects *x* with the same solver, at most ``REFINE_STEPS``
   times (2 with a Krylov segment), stopping once every component's
   correction is below ``REFINE_TOL`` relative. This recovers full float64
   accuracy while ``cond(A) * 1e-16 < 1``.
2. **Iterative fallback**, when the LU factorisation fails (out of memory,
   singular) or the system has more than ``DIRECT_LIMIT`` unknowns:
   Jacobi-preconditioned BiCGSTAB (``rtol = ITERATIVE_RTOL``, at most
   ``ITERATIVE_MAXITER`` iterations) from the best iterate so far, then
   restarted GMRES(60) if BiCGSTAB broke down.

**Acceptance rule** (both paths): the normwise backward error
``||b - A x||_inf / (||A||_inf ||x||_inf + ||b||_inf) <= RESIDUAL_TOL = 1e-10``,
residual in extended precision, and every component finite. A system that
meets neither path's answer raises :class:`~veribattery.errors.CheckError`.
"""

from __future__ import annotations

import hashlib
import weakref
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, cast

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.sparse import linalg as spla

try:  # SuperLU's triangular solve, used by _substitution when it behaves as expected
    from scipy.sparse.linalg._dsolve import _superlu
except ImportError:  # pragma: no cover -- scipy moved it: the public path is used
    _superlu = None

from veribattery._memory import TRIM_MIN_STATES, trim_for
from veribattery._sparse import csc_sharing, csr_sharing
from veribattery._types import BoolArray, CsrMatrix, FloatArray
from veribattery.errors import CheckError

if TYPE_CHECKING:
    from veribattery.checker import scc

ExtArray = npt.NDArray[np.longdouble]

#: Accept a solution whose normwise backward error is at most this.
RESIDUAL_TOL = 1e-10
#: Systems with more unknowns than this skip the LU factorisation.
DIRECT_LIMIT = 4_000_000
#: A system solved by substitution with at least this many unknowns releases its
#: matrix when it can make it again (see :meth:`Factorization._release`).
RELEASE_MIN_STATES = 100_000
#: At most this many extended-precision refinement steps after the LU solve.
REFINE_STEPS = 6
#: Refinement stops once every correction is below this, relative to its component.
REFINE_TOL = 2.0**-52
#: Relative tolerance handed to BiCGSTAB and GMRES.
ITERATIVE_RTOL = 1e-13
#: Iteration cap of each iterative method.
ITERATIVE_MAXITER = 20_000


def restricted_matrix(P: CsrMatrix, maybe: BoolArray) -> tuple[sp.csr_matrix, CsrMatrix]:
    """``I - P[maybe, maybe]`` in extended precision, and the rows ``P[maybe, :]``.

    The diagonal is the probability of leaving each state, summed from the
    off-diagonal entries, rather than ``1 - P_ii``: that cancels
    catastrophically for self-loops close to 1, and rows that do not sum to
    exactly 1 in float64 would leak or gain mass. (Kernels use
    :func:`restricted_parts`, which stores the same matrix in float64.)
    """
    A64, residue, rows = restricted_parts(P, maybe)
    A = A64.astype(np.longdouble) + residue
    return sp.csr_matrix(A), rows


def restricted_parts(P: CsrMatrix, maybe: BoolArray
                     ) -> tuple[sp.csr_matrix, sp.csr_matrix, CsrMatrix]:
    """:func:`restricted_matrix` as ``A64 + residue``: the float64 matrix (diagonal
    rounded to nearest) and the extended-precision rounding residue of the diagonal.

    The off-diagonal entries are stored probabilities, exact in float64, so only
    the diagonal needs more: 8 bytes per state instead of 16 per nonzero. Index
    work depends only on *P*'s pattern and *maybe*, so it is memoised by them
    (:class:`_RestrictionPlan`); the values are then gathered.
    """
    plan = _restriction_plan(P, maybe)
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
    moves = column != row_of
    leave = _row_sums(row_of[moves], rows.data[moves], n)
    leave64 = leave.astype(np.float64)
    keep = moves & (column >= 0) & (rows.data != 0)
    del moves, position, idx
    A64 = _with_diagonal(row_of[keep], column[keep], -rows.data[keep], leave64)
    del row_of, column, keep  # before the residue: these are per entry
    leave -= leave64  # the residue, in place (leave64 widens exactly)
    return A64, _diagonal_residue(leave), rows


#: Digests of index arrays, by the arrays' identity (see :func:`index_digest`).
_INDEX_DIGESTS: OrderedDict[tuple[int, int], tuple[weakref.ref[npt.NDArray[np.integer]],
                                                  weakref.ref[npt.NDArray[np.integer]],
                                                  bytes]] = OrderedDict()
INDEX_DIGESTS_KEPT = 8


def index_digest(indptr: npt.NDArray[np.integer], indices: npt.NDArray[np.integer]) -> bytes:
    """A digest of a sparse matrix's index arrays, memoised by the arrays' identity.

    Matrices of a structure-reusing sweep share their index arrays (the re-evaluated
    transition matrix takes the base's, :func:`veribattery.explore.reuse.reevaluate`;
    a restriction plan's ``A64`` takes the plan's), so each point's pattern lookups
    (pre-pass memo, restriction plan, triangular plan) hash no index array again.
    Index arrays are never modified in place once a matrix is built (as the memos
    here already require).
    """
    key = (id(indptr), id(indices))
    found = _INDEX_DIGESTS.get(key)
    if found is not None and found[0]() is indptr and found[1]() is indices:
        _INDEX_DIGESTS.move_to_end(key)
        return found[2]
    digest = hashlib.blake2b(digest_size=20)
    digest.update(np.ascontiguousarray(indptr).data)
    digest.update(np.ascontiguousarray(indices).data)
    value = digest.digest()
    _INDEX_DIGESTS[key] = (weakref.ref(indptr), weakref.ref(indices), value)
    while len(_INDEX_DIGESTS) > INDEX_DIGESTS_KEPT:
        _INDEX_DIGESTS.popitem(last=False)
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


#: Restriction plans of the last few (pattern, unknown states) pairs (None: seen once).
RESTRICTIONS_KEPT = 8
_RESTRICTIONS: OrderedDict[bytes, _RestrictionPlan | None] = OrderedDict()


def _restriction_plan(P: CsrMatrix, maybe: BoolArray) -> _RestrictionPlan | None:
    """The memoised plan of *P*'s pattern (positions and positive entries) and *maybe*,
    made the second time they are seen (None the first time)."""
    if not P.has_canonical_format:
        return None
    digest = hashlib.blake2b(digest_size=20)
    digest.update(np.asarray(P.shape, dtype=np.int64).tobytes())
    digest.update(index_digest(P.indptr, P.indices))
    digest.update(np.packbits(P.data != 0).data)
    digest.update(np.packbits(maybe).data)
    key = digest.digest()
    plan = None
    if key in _RESTRICTIONS:  # seen before: a sweep re-uses the pattern, worth a plan
        _RESTRICTIONS.move_to_end(key)
        plan = _RESTRICTIONS[key] or _new_restriction(P, maybe)
    # A pattern seen once is only remembered (a single check never pays for a plan).
    _RESTRICTIONS[key] = plan
    while len(_RESTRICTIONS) > RESTRICTIONS_KEPT:
        _RESTRICTIONS.popitem(last=False)
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


def solve(A: sp.csr_matrix, b: ExtArray) -> FloatArray:
    """Solve ``A x = b`` (extended-precision *A* and *b*) under the module's rule.

    :param A: the system matrix from :func:`restricted_matrix`.
    :param b: the right-hand side, in extended precision.
    :raises CheckError: when neither the direct nor the iterative path is accepted.
    """
    return Factorization(A).solve(b)


class Factorization:
    """A system matrix prepared once for any number of right-hand sides.

    The matrix is kept as float64 ``A64`` plus a sparse extended-precision
    ``residue`` (``A = A64 + residue`` exactly; for :func:`restricted_parts` the
    residue is the rounding of the diagonal), so no extended copy of the whole
    matrix is kept; residuals are computed in extended precision a block of
    rows at a time.

    The direct solver is built on the first non-trivial solve and kept: when the
    off-diagonal graph of *A* is acyclic (every strongly connected component a
    single state, as in a mission that only moves forward), *A* is triangular in
    a topological order and the "factorisation" is that permutation, so each
    solve is one sparse substitution; otherwise the system is solved SCC by SCC
    (:mod:`~veribattery.checker.scc`), each component by a method chosen by its size.

    :param A: the system matrix (extended precision or float64).
    :param residue: with a float64 *A*, the extended-precision part ``A_exact - A``.
    """

    def __init__(self, A: sp.csr_matrix, residue: sp.csr_matrix | None = None,
                 rebuild: Callable[[], tuple[sp.csr_matrix, sp.csr_matrix]] | None = None
                 ) -> None:
        if residue is None:
            A, residue = _split(A)
        # (A itself when it is CSR already: a copy would not share the plan's indices)
        self._a64: sp.csr_matrix | None = A if isinstance(A, sp.csr_matrix) else sp.csr_matrix(A)
        self._residue: sp.csr_matrix | None = residue
        self._n = int(A.shape[0])
        self._rebuild = rebuild
        self._direct: _Inverse | None = None
        self._direct_tried = False
        self._substitute: _Triangular | None = None
        self._substitute_tried = False
        self._norm_a: float | None = None
        self._iterative = False

    @property
    def A64(self) -> sp.csr_matrix:
        """The float64 part of the matrix (made again if it was released)."""
        if self._a64 is None:
            self._restore()
        assert self._a64 is not None
        return self._a64

    @property
    def residue(self) -> sp.csr_matrix:
        """The extended-precision rest ``A_exact - A64`` (made again if it was released)."""
        if self._residue is None:
            self._restore()
        assert self._residue is not None
        return self._residue

    def _restore(self) -> None:
        assert self._rebuild is not None
        self._a64, self._residue = self._rebuild()

    def _release(self) -> None:
        """Drop the matrix while only the triangular substitution is needed.

        With *rebuild* (which makes the same matrix again, bit for bit), a large
        system solved by substitution keeps the substitution's own copy only: the
        quick certificate needs no residual, and ``A64`` and its residue (89 MB at
        1.4M states) come back only if a refined solve is asked for.
        """
        if self._rebuild is not None and self._n >= RELEASE_MIN_STATES:
            self._a64 = self._residue = None

    @property
    def A(self) -> sp.csr_matrix:
        """The exact system matrix in extended precision (a new copy: tests, small systems)."""
        return sp.csr_matrix(self.A64.astype(np.longdouble) + self.residue)

    def solve(self, b: ExtArray) -> FloatArray:
        """Solve ``A x = b`` under the module's rule.

        :param b: the right-hand side, in extended precision.
        :raises CheckError: when neither the direct nor the iterative path is accepted.
        """
        n = self._n
        if not b.any():
            return np.zeros(b.shape, dtype=np.float64)
        inverse = self._inverse() if n <= DIRECT_LIMIT else None
        if self._norm_a is None:
            self._norm_a = matrix_norm(self.A64) + matrix_norm(self.residue)
        steps = 2 if self._iterative else REFINE_STEPS
        x = self._refined(inverse, b, steps) if inverse is not None else None
        if x is not None and self.backward_error(x, b) <= RESIDUAL_TOL:
            return x
        x = _solve_iterative(self.A64, b.astype(np.float64), x)
        if not self.backward_error(x, b) <= RESIDUAL_TOL:
            raise CheckError(f"linear solver did not reach backward error {RESIDUAL_TOL:g} "
                             f"on {n} states")
        return x

    def residual(self, x: FloatArray, b: ExtArray) -> ExtArray:
        """``b - A x`` in extended precision, a block of rows at a time."""
        return b - _extended_product(self.A64, self.residue, x)

    def backward_error(self, x: FloatArray, b: ExtArray) -> float:
        """The normwise backward error of *x* (see :func:`backward_error`)."""
        if not np.all(np.isfinite(x)):
            return float("inf")
        if self._norm_a is None:
            self._norm_a = matrix_norm(self.A64) + matrix_norm(self.residue)
        scale = self._norm_a * _norm(x) + _norm(b)
        residual = _norm(self.residual(x, b))
        return residual / scale if scale > 0 else residual


    def _accepted(self, x: FloatArray, b: ExtArray, residual: ExtArray) -> bool:
        """The backward-error rule for *x*, given its residual."""
        if not np.all(np.isfinite(x)) or self._norm_a is None:
            return False
        scale = self._norm_a * _norm(x) + _norm(b)
        error = _norm(residual)
        return (error / scale if scale > 0 else error) <= RESIDUAL_TOL

    def _refined(self, inverse: _Inverse, b: ExtArray, steps: int) -> FloatArray:
        """``inverse(b)``, refined with extended-precision residuals."""
        x: FloatArray = inverse(b.astype(np.float64))
        for _ in range(steps):
            residual = self.residual(x, b)
            if self._iterative and self._accepted(x, b, residual):
                break  # each correction would be a whole Krylov solve: only when needed
            correction: FloatArray = inverse(residual.astype(np.float64))
            x = x + correction
            if not np.all(np.isfinite(x)) or _converged(correction, x):
                break
        return x

    def approximate(self, b: FloatArray) -> FloatArray | None:
        """One application of the direct solver to *b*: no refinement, no acceptance test
        (None when there is no direct solver or the result is not finite).

        For callers that certify the answer anyway and only need the full rule of
        :meth:`solve` when the certified interval comes out too wide.
        """
        if not b.any():
            return np.zeros(b.shape, dtype=np.float64)
        inverse = self._inverse() if self._n <= DIRECT_LIMIT else None
        if inverse is None:
            return None
        return _finite_solve(inverse, np.ascontiguousarray(b, dtype=np.float64))

    def correction(self, v: FloatArray) -> FloatArray | None:
        """An approximate ``A^{-1} v`` for certification margins (None if unavailable).

        The direct solver's factors when there are any (one substitution pass);
        otherwise a full :meth:`solve`. Accuracy only affects how tight the
        certified bounds come out, never their validity.
        """
        if not v.any():
            return np.zeros_like(v)
        inverse = self._inverse() if self._n <= DIRECT_LIMIT else None
        try:
            if inverse is not None:
                return np.asarray(inverse(np.ascontiguousarray(v, dtype=np.float64)))
            return self.solve(v.astype(np.longdouble))
        except (CheckError, RuntimeError):
            return None

    @property
    def iterative(self) -> bool:
        """Whether the direct solver has a Krylov segment (known once it is built)."""
        return self._iterative

    def margins_for(self, b: npt.NDArray[np.floating], x: FloatArray
                    ) -> list[Callable[[FloatArray], FloatArray | None]]:
        """The margin solvers to try, in turn, for the quick certificate of ``x ~ A^-1 b``.

        With a Krylov segment and ``b > 0``, first one without any solve: ``A^-1 >= 0``
        (an M-matrix), so ``A^-1 v <= max(v / b) A^-1 b``, and *x* stands for
        ``A^-1 b`` (the certificate's test decides whether it does well enough;
        the interval is wider than with :meth:`margin` where the defect is uneven).
        Then :meth:`margin`.
        """
        if self._iterative and bool(np.all(b > 0)) and bool(np.all(x > 0)):
            positive = np.asarray(b, dtype=np.float64)

            def proportional(v: FloatArray) -> FloatArray:
                return float(np.max(v / positive, initial=0.0)) * x

            return [proportional, self.margin]
        return [self.margin]

    def margin(self, v: FloatArray) -> FloatArray | None:
        """:meth:`correction` for the quick certificate: with a Krylov segment, a
        loose solve of a lifted *v* (:meth:`scc.Segmented.margin`), else the same."""
        inverse = self._inverse() if self._n <= DIRECT_LIMIT else None
        if inverse is None or not self._iterative:  # iterative: a Krylov segment's inverse
            return self.correction(v)
        if not v.any():
            return np.zeros_like(v)
        segmented = cast("scc.Segmented", inverse)
        return np.asarray(segmented.margin(np.ascontiguousarray(v, dtype=np.float64)))

    @property
    def triangular(self) -> bool:
        """Whether the direct solver is a substitution (the matrix is triangular in a
        topological order, with a positive diagonal). Only that solver is tried here:
        a caller that drops a system that is not triangular pays for no factorisation."""
        return self._n <= DIRECT_LIMIT and self._substitution() is not None

    def pinned(self, mask: BoolArray) -> PinnedSolver | None:
        """A solver of this system with the rows of the states in *mask* replaced by
        identity rows, for the quick certificate of a query solved on it with those
        states' values known (``kernels``, "Shared systems" in docs/numerics.md);
        None unless the direct solver is a substitution."""
        inverse = self._substitution() if self._n <= DIRECT_LIMIT else None
        return None if inverse is None else PinnedSolver(inverse.pinned(mask))

    def dual(self, v: FloatArray) -> FloatArray | None:
        """An approximate ``w`` with ``w^T (I - B) = v^T``, where ``I - B = D^-1 A`` is the
        system with each row divided by its diagonal (the fixed-point map's matrix):
        ``w = D A^-T v``, one transposed substitution. None unless the direct solver is a
        substitution, or when the answer is not finite. For the bounds at a few states
        (:mod:`~veribattery.checker.focus`); accuracy affects only their tightness.
        """
        inverse = self._substitution() if self._n <= DIRECT_LIMIT else None
        if inverse is None:
            return None
        return _finite_solve(inverse.dual, np.asarray(v, dtype=np.float64))

    def _substitution(self) -> _Triangular | None:
        """The substitution solver, tried once (None: the matrix's graph has a cycle)."""
        if not self._substitute_tried:
            self._substitute_tried = True
            self._substitute = _triangular_inverse(self.A64)
            if self._substitute is not None:
                self._release()
                trim_for(self._n)  # the plan's temporaries (and the matrix) are free now
        return self._substitute

    def _inverse(self) -> _Inverse | None:
        if not self._direct_tried:
            self._direct_tried = True
            self._direct = self._substitution()
            if self._direct is None:  # the graph has a cycle: segment it
                from veribattery.checker import scc

                found = scc.components(self.A64)
                if found is not None:
                    segmented = scc.segmented_inverse(self.A64, found)
                    self._iterative = segmented is not None and segmented.iterative
                    self._direct = segmented
            if self._direct is None:
                self._direct = _lu_inverse(self.A64)
        return self._direct


def _finite_solve(inverse: _Inverse, b: FloatArray) -> FloatArray | None:
    """``inverse(b)`` in float64, or None when the solve fails or is not finite."""
    try:
        x = np.asarray(inverse(b), dtype=np.float64)
    except RuntimeError:
        return None
    return x if np.all(np.isfinite(x)) else None


class QuickSolver(Protocol):
    """What the quick certificate needs of a solver (:class:`Factorization`,
    :class:`PinnedSolver`)."""

    def approximate(self, b: FloatArray) -> FloatArray | None: ...

    def margins_for(self, b: npt.NDArray[np.floating], x: FloatArray
                    ) -> list[Callable[[FloatArray], FloatArray | None]]: ...


class PinnedSolver:
    """A substitution whose pinned rows are identity rows (:meth:`Factorization.pinned`):
    unrefined solves only, for the quick certificate."""

    def __init__(self, inverse: _Inverse) -> None:
        self._inverse = inverse

    def approximate(self, b: FloatArray) -> FloatArray | None:
        """One substitution (None when it fails or is not finite)."""
        return _finite_solve(self._inverse, np.asarray(b, dtype=np.float64))

    def margins_for(self, b: npt.NDArray[np.floating], x: FloatArray
                    ) -> list[Callable[[FloatArray], FloatArray | None]]:
        """The margin solver: the same substitution."""
        return [self.approximate]


def _split(A: sp.csr_matrix) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """*A* as float64 plus its extended-precision rounding residue (zeros not stored)."""
    A = sp.csr_matrix(A)
    A64 = sp.csr_matrix(A.astype(np.float64))
    A64.sort_indices()
    if A.dtype != np.longdouble:
        return A64, sp.csr_matrix(A.shape, dtype=np.longdouble)
    residue = sp.csr_matrix(A - A64.astype(np.longdouble))
    residue.eliminate_zeros()
    return A64, residue


#: Nonzeros per block of the extended-precision product (bounds its temporary copy).
_PRODUCT_BLOCK = 1 << 20


def extended_product(M: CsrMatrix, x: FloatArray) -> ExtArray:
    """``M x`` in extended precision, as ``M.astype(longdouble) @ x`` computes it (same
    order of summation) but widening *M* a block of rows at a time."""
    return _extended_product(M, None, x)


def _extended_product(A64: sp.csr_matrix, residue: sp.csr_matrix | None,
                      x: FloatArray) -> ExtArray:
    """``(A64 + residue) x`` in extended precision, *A64* converted a block at a time."""
    n = A64.shape[0]
    x_ext = np.asarray(x, dtype=np.longdouble)
    out = np.empty(n, dtype=np.longdouble)
    step = max(1, _PRODUCT_BLOCK * n // max(A64.nnz, 1))
    for lo in range(0, n, step):
        hi = min(n, lo + step)
        start, stop = A64.indptr[lo], A64.indptr[hi]
        block = sp.csr_matrix((A64.data[start:stop].astype(np.longdouble),
                               A64.indices[start:stop], A64.indptr[lo:hi + 1] - start),
                              shape=(hi - lo, A64.shape[1]))
        out[lo:hi] = block @ x_ext
    if residue is not None and residue.nnz:
        out += residue @ x_ext
    return out


#: Applies an approximate inverse of the system matrix to a float64 vector.
_Inverse = Callable[[FloatArray], FloatArray]


def _lu_inverse(A64: sp.csr_matrix) -> _Inverse | None:
    """SuperLU's factors of *A64* (None if the factorisation fails)."""
    try:
        lu = spla.splu(A64.tocsc())
    except (RuntimeError, MemoryError):
        return None
    return lu.solve  # type: ignore[no-any-return]


@dataclass(frozen=True, slots=True)
class _TriangularPlan:
    """What :func:`_triangular_inverse` derives from *A64*'s sparsity pattern alone.

    Matrices of one pattern (a structure-reusing sweep: same states and transitions,
    other probabilities) share it, so only the values are gathered anew.

    :param order: ``order[k]`` is the state at topological position *k*.
    :param diagonal_at: per position, the index of its diagonal entry in ``A64.data``.
    :param gather: ``A64.data`` indices in the order of the CSC data of the
        permuted lower-triangular matrix.
    (Index arrays are stored as int32, as scipy's own for these sizes.)
    """

    order: npt.NDArray[np.int32]
    diagonal_at: npt.NDArray[np.int32]
    gather: npt.NDArray[np.int32]
    indices: npt.NDArray[np.intc]
    indptr: npt.NDArray[np.intc]

    def columns(self) -> npt.NDArray[np.int64]:
        """The (permuted) column of each entry of the CSC data."""
        return np.repeat(np.arange(self.indptr.size - 1), np.diff(self.indptr))


#: Plans of the last few patterns, by digest (see :func:`_pattern_digest`).
PLANS_KEPT = 4
_PLANS: OrderedDict[bytes, _TriangularPlan | None] = OrderedDict()
#: Patterns whose plan was made once and not kept: a plan (~40 MB at 1.4M states) is
#: kept only for a pattern seen again (a structure-reusing sweep), as restrictions are.
_PLANS_SEEN: OrderedDict[bytes, None] = OrderedDict()


def _pattern_digest(A64: sp.csr_matrix) -> bytes:
    """A digest of *A64*'s shape and stored positions (not its values)."""
    digest = hashlib.blake2b(digest_size=20)
    digest.update(np.asarray(A64.shape, dtype=np.int64).tobytes())
    digest.update(index_digest(A64.indptr, A64.indices))
    return digest.digest()


def _triangular_plan(A64: sp.csr_matrix) -> _TriangularPlan | None:
    """The plan of *A64*'s pattern (None if its graph has a cycle), memoised by pattern."""
    A64.sum_duplicates()  # canonical: one stored entry per position
    key = _pattern_digest(A64)
    if key in _PLANS:
        _PLANS.move_to_end(key)
        return _PLANS[key]
    plan = _new_plan(A64)
    if plan is not None and key not in _PLANS_SEEN:
        _PLANS_SEEN[key] = None
        while len(_PLANS_SEEN) > RESTRICTIONS_KEPT:
            _PLANS_SEEN.popitem(last=False)
        return plan
    _PLANS_SEEN.pop(key, None)
    _PLANS[key] = plan
    while len(_PLANS) > PLANS_KEPT:
        _PLANS.popitem(last=False)
    return plan


def _new_plan(A64: sp.csr_matrix) -> _TriangularPlan | None:
    """Topological positions from the SCC labelling (Tarjan/Pearce numbers them in
    reverse topological order), checked against the pattern: lower triangular.

    Every per-entry temporary is int32 when the sizes allow (at 4M nonzeros an int64
    copy is 33 MB, and this ran five of them at once), and the entries are turned
    into column order by scipy's two counting passes on int32 tags.
    """
    n = A64.shape[0]
    count, labels = csgraph.connected_components(A64, directed=True, connection="strong")
    if count != n:
        return None
    index = np.int32 if max(A64.nnz, n) < 2**31 - 1 else np.int64
    position = labels.astype(index, copy=False)
    del labels
    rows = np.repeat(position, np.diff(A64.indptr))  # the position of each entry's row
    cols = position[A64.indices]
    if np.any(cols > rows):  # not the order expected: try the opposite one
        position = (n - 1) - position
        np.subtract(n - 1, rows, out=rows)
        np.subtract(n - 1, cols, out=cols)
        if np.any(cols > rows):
            return None
    on_diagonal = np.flatnonzero(rows == cols)
    if on_diagonal.size != n:
        return None
    diagonal_at = np.empty(n, dtype=index)
    diagonal_at[rows[on_diagonal]] = on_diagonal
    del on_diagonal
    # The entries in (column, row) order: COO -> CSR -> CSC, rows ascending within
    # each column, on tags 1..nnz (CSR's duplicate summing drops zeros: no tag is 0).
    tags = np.arange(1, A64.nnz + 1, dtype=index)
    by_row = sp.csr_matrix((tags, (rows, cols)), shape=(n, n))
    del tags, rows, cols
    by_column = by_row.tocsc()
    del by_row
    gather = by_column.data
    gather -= 1
    order = np.empty(n, dtype=index)
    order[position] = np.arange(n, dtype=index)
    return _TriangularPlan(order, diagonal_at, gather,
                           np.asarray(by_column.indices, dtype=np.intc),
                           np.asarray(by_column.indptr, dtype=np.intc))


def _triangular_inverse(A64: sp.csr_matrix) -> _Triangular | None:
    """Substitution in a topological order of *A64*'s graph; None if that has a cycle.

    The permutation and the triangular matrix's structure come from the pattern's
    plan (:func:`_triangular_plan`, shared by matrices of one pattern); the values
    are gathered from *A64*: a state's successors precede it, so the permuted
    matrix is lower triangular.
    """
    plan = _triangular_plan(A64)
    if plan is None:
        return None
    diagonal = np.asarray(A64.data[plan.diagonal_at], dtype=np.float64)
    if not np.all(diagonal > 0):
        return None
    scale = 1.0 / diagonal
    # Columns scaled to a unit diagonal: L y = b, then x = y / diagonal (each
    # column's scale repeated over its entries: no per-entry index array).
    data = A64.data[plan.gather]
    data *= np.repeat(scale, np.diff(plan.indptr))
    n = A64.shape[0]
    lower = csc_sharing(data, plan.indices, plan.indptr, (n, n))
    return _Triangular(lower, _substitution(lower), plan.order, scale)


class _Triangular:
    """The substitution of :func:`_triangular_inverse`: ``A x = b`` with ``A = L D`` in
    a topological order (``L`` unit lower triangular, ``D`` the diagonal of *A*)."""

    def __init__(self, lower: sp.csc_matrix, substitute: _Inverse,
                 order: npt.NDArray[np.integer], scale: FloatArray) -> None:
        self._lower, self._substitute, self._order, self._scale = lower, substitute, order, scale
        self._transposed: _Inverse | None = None  # made on the first dual solve
        n = order.size
        # Index arrays of numpy's own index type (others are converted at every use)
        # and the inverse permutation, so that both ends of a solve are gathers;
        # only for systems that do not keep a plan's int32 arrays for their memory.
        self._forward: npt.NDArray[np.intp] | None = None
        self._back: npt.NDArray[np.intp] | None = None
        if n < TRIM_MIN_STATES:
            self._forward = np.asarray(order, dtype=np.intp)
            self._back = np.empty(n, dtype=np.intp)
            self._back[self._forward] = np.arange(n, dtype=np.intp)

    def __call__(self, b: FloatArray) -> FloatArray:
        return self._from_order(self._substitute(self._to_order(b)))

    def _to_order(self, b: npt.NDArray[np.floating]) -> FloatArray:
        """*b* in topological order: a new array, which the substitution may solve in."""
        if self._forward is None:
            return np.ascontiguousarray(b[self._order], dtype=np.float64)
        return np.take(np.asarray(b, dtype=np.float64), self._forward)

    def _from_order(self, y: FloatArray) -> FloatArray:
        """The answer of the substitution's *y* (scaled in place) in state order."""
        y *= self._scale
        return self._in_state_order(y)

    def _in_state_order(self, y: FloatArray) -> FloatArray:
        """*y*, given in topological order, in state order (a new array)."""
        if self._back is None:
            x = np.empty(y.size, dtype=np.float64)
            x[self._order] = y
            return x
        return np.take(y, self._back)

    def dual(self, v: FloatArray) -> FloatArray:
        """``D A^-T v``: ``A^T = D L^T`` in the topological order, so ``L^T y = D^-1 v``
        by a transposed substitution with the same factor, then ``D y``."""
        if self._transposed is None:
            self._transposed = _substitution(self._lower, transposed=True)
        c = self._to_order(v)
        c *= self._scale
        y = self._transposed(c)
        y /= self._scale
        return self._in_state_order(y)

    def pinned(self, mask: BoolArray) -> _Inverse:
        """Solves the system whose rows of the states in *mask* are identity rows
        (``x_i = b_i`` there, the other rows as in *A*): *L* without those rows'
        off-diagonal entries, the same order. The pinned entries of the answer are
        *b*'s own (the substitution's ``(b_i d_i) / d_i`` may differ in the last bit)."""
        scale, lower = self._scale, self._lower
        at = mask[self._order]  # per topological position
        data = np.where(at[lower.indices], 0.0, lower.data)  # column i's own entry is on
        data[lower.indptr[:-1][at]] = 1.0  # the diagonal: it stays (first in the column)
        substitute = _substitution(sp.csc_matrix((data, lower.indices, lower.indptr),
                                                 shape=lower.shape))
        where = np.flatnonzero(mask)

        def apply(b: FloatArray) -> FloatArray:
            c = self._to_order(b)
            c[at] /= scale[at]  # y_i = d_i b_i, so that x_i = y_i / d_i is b_i
            x = self._from_order(substitute(c))
            x[where] = b[where]
            return x

        return apply


def _substitution(lower: sp.csc_matrix, *, transposed: bool = False) -> _Inverse:
    """Forward substitution with the unit lower-triangular CSC matrix *lower* (with
    *transposed*, backward substitution with its transpose; the returned function may
    overwrite its argument with the solution).

    SuperLU's triangular solve on prepared arrays (what ``spsolve_triangular``
    calls after copying and rescaling its argument each time); the public
    function is the fallback should that private entry point change.
    """
    n = lower.shape[0]
    # Views of *lower*'s arrays when they have these types (a copy would keep a
    # second set of indices alive for as long as the solver).
    data = np.ascontiguousarray(lower.data, dtype=np.float64)
    indices = np.ascontiguousarray(lower.indices, dtype=np.intc)
    indptr = np.ascontiguousarray(lower.indptr, dtype=np.intc)
    empty_data = np.zeros(0, dtype=np.float64)
    empty_indices = np.zeros(0, dtype=np.intc)
    empty_indptr = np.zeros(n + 1, dtype=np.intc)

    def private(b: FloatArray) -> FloatArray:
        # (b is overwritten: callers pass an array of their own, no copy made here)
        x, info = _superlu.gstrs(trans, n, data.size, data, indices, indptr,
                                 n, 0, empty_data, empty_indices, empty_indptr, b)
        if info:
            raise RuntimeError("triangular solve failed")
        return np.asarray(x, dtype=np.float64)

    def public(b: FloatArray) -> FloatArray:
        matrix = lower.T.tocsc() if transposed else lower
        x = spla.spsolve_triangular(matrix, b, lower=not transposed, unit_diagonal=True)
        return np.asarray(x, dtype=np.float64)

    trans = "T" if transposed else "N"
    try:
        if _superlu is None:
            return public
        if trans in _PRIVATE_CHECKED:
            return private
        probe = private(np.ones(n, dtype=np.float64))
        product = lower.T @ probe if transposed else lower @ probe
        if np.all(np.isfinite(probe)) and np.allclose(product, 1.0):
            _PRIVATE_CHECKED.add(trans)
            return private
    except Exception:
        pass
    return public


#: The modes ("N", "T") in which the private triangular solve has been seen to solve
#: ``L y = 1`` / ``L^T y = 1`` (a property of the installed scipy, probed once per process).
_PRIVATE_CHECKED: set[str] = set()


def backward_error(A: sp.csr_matrix, x: FloatArray, b: ExtArray,
                   norm_a: float | None = None) -> float:
    """``||b - A x|| / (||A|| ||x|| + ||b||)`` in the infinity norm (inf if x is not finite).

    :param norm_a: ``||A||_inf`` if already known.
    """
    if not np.all(np.isfinite(x)):
        return float("inf")
    residual = _norm(b - A @ x.astype(np.longdouble))
    if norm_a is None:
        norm_a = matrix_norm(A)
    scale = norm_a * _norm(x) + _norm(b)
    return residual / scale if scale > 0 else residual


def matrix_norm(A: sp.csr_matrix) -> float:
    """``||A||_inf``: the largest absolute row sum."""
    row_of = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    sums = np.bincount(row_of, weights=np.abs(A.data).astype(np.float64), minlength=A.shape[0])
    return _norm(np.asarray(sums, dtype=np.float64))


def _norm(v: npt.NDArray[np.floating]) -> float:
    return float(np.max(np.abs(v), initial=0.0))


def _converged(correction: FloatArray, x: FloatArray) -> bool:
    """Every correction below REFINE_TOL relative to its component (zero stays zero)."""
    return bool(np.all(np.abs(correction) <= REFINE_TOL * np.abs(x)))


def _solve_iterative(A: sp.csr_matrix, b: FloatArray, x0: FloatArray | None) -> FloatArray:
    """BiCGSTAB, then restarted GMRES if BiCGSTAB breaks down; Jacobi-preconditioned.

    Both start from *x0* when it is finite (a rejected LU answer is still a good guess).
    """
    x = x0 if x0 is not None and np.all(np.isfinite(x0)) else np.zeros_like(b)
    inverse_diagonal = 1.0 / A.diagonal()
    jacobi = spla.LinearOperator(A.shape, matvec=lambda v: inverse_diagonal * v)
    options = {"rtol": ITERATIVE_RTOL, "atol": 0.0, "M": jacobi}
    # A breakdown shows up as overflow inside BiCGSTAB; the result is judged below
    # by the backward-error rule, so the floating-point warnings carry no news.
    with np.errstate(all="ignore"):
        candidate, _ = spla.bicgstab(A, b, x0=x, maxiter=ITERATIVE_MAXITER, **options)
    if np.all(np.isfinite(candidate)):
        x = candidate
    if backward_error(A, x, b.astype(np.longdouble)) > RESIDUAL_TOL:
        restart = min(A.shape[0], 60)
        # GMRES counts restart cycles, so the cap is in inner iterations as well.
        x, _ = spla.gmres(A, b, x0=x, restart=restart,
                          maxiter=max(1, ITERATIVE_MAXITER // restart), **options)
    return np.asarray(x, dtype=np.float64)
