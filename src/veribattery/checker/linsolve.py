"""Sparse linear systems ``(I - P_mm) x = b`` of the unbounded kernels, and their stopping rule.

The systems are nonsingular M-matrices (the qualitative pre-pass removed every
state that cannot leave the restricted set), but on long chains they are badly
conditioned: a symmetric random walk over n states has condition number ~n².
A plain LU solve there loses digits (1e-6 relative error at n = 10⁶), so:

1. **Direct.** SuperLU factorises the float64 matrix; then *mixed-precision
   iterative refinement* computes each residual ``b - A x`` in extended precision
   (``numpy.longdouble``, 64-bit mantissa on x86-64; elsewhere it may be float64
   and refinement only tightens the backward error) and corrects *x* with the
   LU factors, at most ``REFINE_STEPS`` times, stopping once every component's
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

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse import linalg as spla

from veribattery._types import BoolArray, CsrMatrix, FloatArray
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
    exactly 1 in float64 would leak or gain mass.
    """
    idx = np.flatnonzero(maybe)
    rows = sp.csr_matrix(P[idx])
    row_of = np.repeat(np.arange(idx.size), np.diff(rows.indptr))
    moves = rows.indices != idx[row_of]
    leave = _row_sums(row_of[moves], rows.data[moves].astype(np.longdouble), idx.size)
    inner = sp.csr_matrix(rows[:, idx])
    off = sp.csr_matrix(inner - sp.diags(inner.diagonal(), format="csr"))
    off.eliminate_zeros()
    A = sp.diags(leave, format="csr") - off.astype(np.longdouble)
    return sp.csr_matrix(A), rows


def _row_sums(row_of: npt.NDArray[np.int64], data: ExtArray, n: int) -> ExtArray:
    """Per-row sums of sorted (row, value) pairs, in extended precision."""
    counts = np.bincount(row_of, minlength=n)
    sums = np.zeros(n, dtype=np.longdouble)
    present = counts > 0
    if data.size:
        starts = np.cumsum(counts) - counts
        sums[present] = np.add.reduceat(data, starts[present])
    return sums


def solve(A: sp.csr_matrix, b: ExtArray) -> FloatArray:
    """Solve ``A x = b`` (extended-precision *A* and *b*) under the module's rule.

    :param A: the system matrix from :func:`restricted_matrix`.
    :param b: the right-hand side, in extended precision.
    :raises CheckError: when neither the direct nor the iterative path is accepted.
    """
    if not b.any():
        return np.zeros(b.shape, dtype=np.float64)
    A64 = sp.csr_matrix(A.astype(np.float64))
    x = _solve_direct(A, A64, b) if A.shape[0] <= DIRECT_LIMIT else None
    if x is not None and backward_error(A, x, b) <= RESIDUAL_TOL:
        return x
    x = _solve_iterative(A64, b.astype(np.float64), x)
    if not backward_error(A, x, b) <= RESIDUAL_TOL:
        raise CheckError(f"linear solver did not reach backward error {RESIDUAL_TOL:g} "
                         f"on {A.shape[0]} states")
    return x


def backward_error(A: sp.csr_matrix, x: FloatArray, b: ExtArray) -> float:
    """``||b - A x|| / (||A|| ||x|| + ||b||)`` in the infinity norm (inf if x is not finite)."""
    if not np.all(np.isfinite(x)):
        return float("inf")
    residual = _norm(b - A @ x.astype(np.longdouble))
    norm_a = _norm(np.asarray(abs(A).sum(axis=1)).ravel())
    scale = norm_a * _norm(x) + _norm(b)
    return residual / scale if scale > 0 else residual


def _norm(v: npt.NDArray[np.floating]) -> float:
    return float(np.max(np.abs(v), initial=0.0))


def _solve_direct(A: sp.csr_matrix, A64: sp.csr_matrix, b: ExtArray) -> FloatArray | None:
    """LU in float64, refined with extended-precision residuals; None if LU fails."""
    try:
        lu = spla.splu(A64.tocsc())
    except (RuntimeError, MemoryError):
        return None
    x: FloatArray = lu.solve(b.astype(np.float64))
    for _ in range(REFINE_STEPS):
        residual = (b - A @ x.astype(np.longdouble)).astype(np.float64)
        correction: FloatArray = lu.solve(residual)
        x = x + correction
        if not np.all(np.isfinite(x)) or _converged(correction, x):
            break
    return x


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
    candidate, _ = spla.bicgstab(A, b, x0=x, maxiter=ITERATIVE_MAXITER, **options)
    if np.all(np.isfinite(candidate)):
        x = candidate
    if backward_error(A, x, b.astype(np.longdouble)) > RESIDUAL_TOL:
        restart = min(A.shape[0], 60)
        # GMRES counts restart cycles, so the cap is in inner iterations as well.
        x, _ = spla.gmres(A, b, x0=x, restart=restart,
                          maxiter=max(1, ITERATIVE_MAXITER // restart), **options)
    return np.asarray(x, dtype=np.float64)
