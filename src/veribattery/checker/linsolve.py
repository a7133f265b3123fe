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

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.sparse import linalg as spla

try:  # SuperLU's triangular solve, used by _substitution when it behaves as expected
    from scipy.sparse.linalg._dsolve import _superlu
except ImportError:  # pragma: no cover -- scipy moved it: the public path is used
    _superlu = None

from veribattery._types import BoolArray, CsrMatrix, FloatArray
from veribattery.checker import scc
from veribattery.errors import CheckError

ExtArray = npt.NDArray[np.longdouble]

#: Accept a solution whose normwise backward error is at most this.
RESIDUAL_TOL = 1e-10
#: Systems with more unknowns than this skip the LU factorisation.
DIRECT_LIMIT = 4_000_000
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
    the diagonal needs more: 8 bytes per state instead of 16 per nonzero.
    """
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
    del moves
    A64 = _with_diagonal(row_of[keep], column[keep], -rows.data[keep], leave64)
    return A64, _diagonal_residue(leave - leave64.astype(np.longdouble)), rows


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
    where = np.flatnonzero(residue)
    n = residue.size
    return sp.csr_matrix((residue[where], (where, where)), shape=(n, n), dtype=np.longdouble)


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

    def __init__(self, A: sp.csr_matrix, residue: sp.csr_matrix | None = None) -> None:
        if residue is None:
            A, residue = _split(A)
        self.A64 = sp.csr_matrix(A)
        self.residue = residue
        self._direct: _Inverse | None = None
        self._direct_tried = False
        self._norm_a: float | None = None
        self._iterative = False

    @property
    def A(self) -> sp.csr_matrix:
        """The exact system matrix in extended precision (a new copy: tests, small systems)."""
        return sp.csr_matrix(self.A64.astype(np.longdouble) + self.residue)

    def solve(self, b: ExtArray) -> FloatArray:
        """Solve ``A x = b`` under the module's rule.

        :param b: the right-hand side, in extended precision.
        :raises CheckError: when neither the direct nor the iterative path is accepted.
        """
        n = self.A64.shape[0]
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

    def correction(self, v: FloatArray) -> FloatArray | None:
        """An approximate ``A^{-1} v`` for certification margins (None if unavailable).

        The direct solver's factors when there are any (one substitution pass);
        otherwise a full :meth:`solve`. Accuracy only affects how tight the
        certified bounds come out, never their validity.
        """
        if not v.any():
            return np.zeros_like(v)
        inverse = self._inverse() if self.A64.shape[0] <= DIRECT_LIMIT else None
        try:
            if inverse is not None:
                return np.asarray(inverse(np.ascontiguousarray(v, dtype=np.float64)))
            return self.solve(v.astype(np.longdouble))
        except (CheckError, RuntimeError):
            return None

    def _inverse(self) -> _Inverse | None:
        if not self._direct_tried:
            self._direct_tried = True
            self._direct = _triangular_inverse(self.A64)
            if self._direct is None:
                found = scc.components(self.A64)
                if found is not None:
                    segmented = scc.segmented_inverse(self.A64, found)
                    self._iterative = segmented is not None and segmented.iterative
                    self._direct = segmented
            if self._direct is None:
                self._direct = _lu_inverse(self.A64)
        return self._direct


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


def _triangular_inverse(A64: sp.csr_matrix) -> _Inverse | None:
    """Substitution in a topological order of *A64*'s graph; None if that has a cycle.

    The strongly connected components come numbered in reverse topological order
    (Tarjan/Pearce), which the permuted pattern is checked against: a state's
    successors precede it, so the permuted matrix is lower triangular.
    """
    n = A64.shape[0]
    count, labels = csgraph.connected_components(A64, directed=True, connection="strong")
    if count != n:
        return None
    coo = A64.tocoo()
    position = labels.astype(np.int64)
    rows, cols = position[coo.row], position[coo.col]
    if np.any(cols > rows):  # not the order expected: try the opposite one
        position = n - 1 - position
        rows, cols = n - 1 - rows, n - 1 - cols
        if np.any(cols > rows):
            return None
    diagonal = np.zeros(n, dtype=np.float64)
    on_diagonal = rows == cols
    np.add.at(diagonal, rows[on_diagonal], coo.data[on_diagonal])
    if not np.all(diagonal > 0):
        return None
    scale = 1.0 / diagonal
    # Columns scaled to a unit diagonal: L y = b, then x = y / diagonal.
    lower = sp.csc_matrix((coo.data * scale[cols], (rows, cols)), shape=(n, n))
    lower.sum_duplicates()
    substitute = _substitution(lower)
    order = np.empty(n, dtype=np.int64)
    order[position] = np.arange(n)

    def apply(b: FloatArray) -> FloatArray:
        x = np.empty(n, dtype=np.float64)
        x[order] = substitute(np.ascontiguousarray(b[order], dtype=np.float64)) * scale
        return x

    return apply


def _substitution(lower: sp.csc_matrix) -> _Inverse:
    """Forward substitution with the unit lower-triangular CSC matrix *lower*.

    SuperLU's triangular solve on prepared arrays (what ``spsolve_triangular``
    calls after copying and rescaling its argument each time); the public
    function is the fallback should that private entry point change.
    """
    n = lower.shape[0]
    data = np.ascontiguousarray(lower.data, dtype=np.float64)
    indices = lower.indices.astype(np.intc)
    indptr = lower.indptr.astype(np.intc)
    empty_data = np.zeros(0, dtype=np.float64)
    empty_indices = np.zeros(0, dtype=np.intc)
    empty_indptr = np.zeros(n + 1, dtype=np.intc)

    def private(b: FloatArray) -> FloatArray:
        x, info = _superlu.gstrs("N", n, data.size, data, indices, indptr,
                                 n, 0, empty_data, empty_indices, empty_indptr, b.copy())
        if info:
            raise RuntimeError("triangular solve failed")
        return np.asarray(x, dtype=np.float64)

    def public(b: FloatArray) -> FloatArray:
        x = spla.spsolve_triangular(lower, b, lower=True, unit_diagonal=True)
        return np.asarray(x, dtype=np.float64)

    try:
        if _superlu is None:
            return public
        probe = private(np.ones(n, dtype=np.float64))
        if np.all(np.isfinite(probe)) and np.allclose(lower @ probe, 1.0):
            return private
    except Exception:
        pass
    return public


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
