"""Sparse linear systems ``(I - P_mm) x = b`` of the unbounded kernels, and their stopping rule.

The systems are nonsingular M-matrices (the qualitative pre-pass removed every
state that cannot leave the restricted set), but on long chains they are badly
conditioned: a symmetric random walk over n states has condition number ~n².
A plain LU solve there loses digits (1e-6 relative error at n = 10⁶), so:

1. **Direct.** A substitution (acyclic systems) or the SCC-wise solve of
   :mod:`~veribattery.checker.linalg.scc` (LU per segment, or preconditioned Krylov
   inside components too large to factorise), on the float64 matrix; then
   *mixed-precision iterative refinement* computes each residual ``b - A x``
   in extended precision (``numpy.longdouble``, 64-bit mantissa on x86-64;
   elsewhere it may be float64 and refinement only tightens the backward
   error) and corrects *x* with the same solver, at most ``REFINE_STEPS``
   times (2 with a Krylov segment), stopping once every component's
   correction is below ``REFINE_TOL`` relative. This recovers full float64
   accuracy while ``cond(A) * 1e-16 < 1``.
   Above ``DIRECT_LIMIT`` unknowns no whole-system LU is tried: a system that
   is not acyclic is solved SCC by SCC in topological order
   (:class:`~veribattery.checker.linalg.topological.TopologicalSolver`) when
   every component has at most ``DIRECT_LIMIT`` states.
2. **Iterative fallback**, when the LU factorisation fails (out of memory,
   singular) or a system above ``DIRECT_LIMIT`` has a larger component:
   Jacobi-preconditioned BiCGSTAB (``rtol = ITERATIVE_RTOL``, at most
   ``ITERATIVE_MAXITER`` iterations) from the best iterate so far, then
   restarted GMRES(60) if BiCGSTAB broke down.

**Acceptance rule** (both paths): the normwise backward error
``||b - A x||_inf / (||A||_inf ||x||_inf + ||b||_inf) <= RESIDUAL_TOL = 1e-10``,
residual in extended precision, and every component finite. A system that
meets neither path's answer raises :class:`~veribattery.errors.CheckError`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol, cast

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse import linalg as spla

from veribattery._sparse import csr_rows
from veribattery._types import BoolArray, CsrMatrix, FloatArray
from veribattery.checker.linalg.compact_lu import compact_solve
from veribattery.checker.linalg.iterative import RESIDUAL_TOL, _norm, matrix_norm, solve_iterative
from veribattery.checker.linalg.monitor import SolveMonitor
from veribattery.checker.linalg.topological import TopologicalSolver, direct_component
from veribattery.checker.linalg.triangular import _Triangular, _triangular_inverse
from veribattery.errors import CheckError

if TYPE_CHECKING:
    from veribattery.checker.linalg import scc
    from veribattery.checker.linalg.restriction import ExtArray, SolverPlans


#: Systems with more unknowns than this skip the whole-system LU factorisation
#: (and the segmented solve): substitution, else the topological solve.
DIRECT_LIMIT = 4_000_000
#: A system solved by substitution with at least this many unknowns releases its
#: matrix when it can make it again (see :meth:`Factorization._release`).
RELEASE_MIN_STATES = 100_000
#: At most this many extended-precision refinement steps after the LU solve.
REFINE_STEPS = 6
#: Refinement stops once every correction is below this, relative to its component.
REFINE_TOL = 2.0**-52
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
    (:mod:`~veribattery.checker.linalg.scc`), each component by a method chosen by its size.

    :param A: the system matrix (extended precision or float64).
    :param residue: with a float64 *A*, the extended-precision part ``A_exact - A``.
    :param rebuild: makes ``(A64, residue)`` again, bit for bit (see :meth:`_release`).
    :param plans: where substitution plans are kept for later matrices of the same
        pattern (None: nothing is kept).
    :param monitor: told how far each solve is (after each segment of an SCC-wise
        solve, each iteration of the iterative fallback; before and after a solve in
        one call), when someone listens to it.
    """

    def __init__(self, A: sp.csr_matrix, residue: sp.csr_matrix | None = None,
                 rebuild: Callable[[], tuple[sp.csr_matrix, sp.csr_matrix]] | None = None,
                 plans: SolverPlans | None = None, monitor: SolveMonitor | None = None) -> None:
        if residue is None:
            A, residue = _split(A)
        # (A itself when it is CSR already: a copy would not share the plan's indices)
        self._a64: sp.csr_matrix | None = A if isinstance(A, sp.csr_matrix) else sp.csr_matrix(A)
        self._residue: sp.csr_matrix | None = residue
        self._n = int(A.shape[0])
        self._rebuild = rebuild
        self._plans = plans
        self.monitor = monitor
        self._direct: _Inverse | None = None
        self._direct_tried = False
        self._substitute: _Triangular | None = None
        self._substitute_tried = False
        self._norm_a: float | None = None
        self._wide: sp.csr_matrix | None = None  # A64 in extended precision, small systems
        self._iterative = False
        self._segmented = False  # the direct solver is an scc.Segmented

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
            self._a64 = self._residue = self._wide = None

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
        inverse = self._inverse()
        if self._norm_a is None:
            self._norm_a = matrix_norm(self.A64) + matrix_norm(self.residue)
        steps = 2 if self._iterative else REFINE_STEPS
        x = self._refined(inverse, b, steps) if inverse is not None else None
        if x is not None and self.backward_error(x, b) <= RESIDUAL_TOL:
            return x
        monitor = self.monitor if self.monitor is not None and self.monitor.heard else None
        x = solve_iterative(self.A64, b.astype(np.float64), x, monitor)
        if not self.backward_error(x, b) <= RESIDUAL_TOL:
            raise CheckError(f"linear solver did not reach backward error {RESIDUAL_TOL:g} "
                             f"on {n} states")
        return x

    def residual(self, x: FloatArray, b: ExtArray) -> ExtArray:
        """``b - A x`` in extended precision, a block of rows at a time (a system within
        one block keeps its widened matrix: a distribution solves one per level)."""
        A64 = self.A64
        if A64.nnz > _PRODUCT_BLOCK:
            return b - _extended_product(A64, self.residue, x)
        if self._wide is None:
            self._wide = sp.csr_matrix((A64.data.astype(np.longdouble), A64.indices,
                                        A64.indptr), shape=A64.shape)
        x_ext = np.asarray(x, dtype=np.longdouble)
        product: ExtArray = self._wide @ x_ext
        if self.residue.nnz:
            product += self.residue @ x_ext
        return b - product

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
        inverse = self._reporting(inverse)
        x: FloatArray = inverse(b.astype(np.float64))
        for _ in range(steps):
            residual = self.residual(x, b)
            if self._iterative and self._accepted(x, b, residual):
                break  # each correction would be a whole Krylov solve: only when needed
            correction: FloatArray = inverse(residual.astype(np.float64))
            with np.errstate(invalid="ignore"):  # inf - inf: not finite, stops below
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
        inverse = self._inverse()
        if inverse is None:
            return None
        return _finite_solve(self._reporting(inverse), np.ascontiguousarray(b, dtype=np.float64))

    def correction(self, v: FloatArray) -> FloatArray | None:
        """An approximate ``A^{-1} v`` for certification margins (None if unavailable).

        The direct solver's factors when there are any (one substitution pass);
        otherwise a full :meth:`solve`. Accuracy only affects how tight the
        certified bounds come out, never their validity.
        """
        if not v.any():
            return np.zeros_like(v)
        inverse = self._inverse()
        try:
            if inverse is not None:
                applied = self._reporting(inverse)
                return np.asarray(applied(np.ascontiguousarray(v, dtype=np.float64)))
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
        inverse = self._inverse()
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
        return self._substitution() is not None

    def pinned(self, mask: BoolArray) -> PinnedSolver | None:
        """A solver of this system with the rows of the states in *mask* replaced by
        identity rows, for the quick certificate of a query solved on it with those
        states' values known (``kernels``, "Shared systems" in docs/numerics.md);
        None unless the direct solver is a substitution."""
        inverse = self._substitution()
        return None if inverse is None else PinnedSolver(inverse.pinned(mask))

    def dual(self, v: FloatArray) -> FloatArray | None:
        """An approximate ``w`` with ``w^T (I - B) = v^T``, where ``I - B = D^-1 A`` is the
        system with each row divided by its diagonal (the fixed-point map's matrix):
        ``w = D A^-T v``, one transposed substitution. None unless the direct solver is a
        substitution, or when the answer is not finite. For the bounds at a few states
        (:mod:`~veribattery.checker.certify.focus`); accuracy affects only their tightness.
        """
        inverse = self._substitution()
        if inverse is None:
            return None
        return _finite_solve(self._reporting(inverse.dual), np.asarray(v, dtype=np.float64))

    def _substitution(self) -> _Triangular | None:
        """The substitution solver, tried once (None: the matrix's graph has a cycle)."""
        if not self._substitute_tried:
            self._substitute_tried = True
            self._substitute = _triangular_inverse(self.A64, self._plans)
            if self._substitute is not None:
                self._release()
        return self._substitute

    def _factorised(self) -> _Inverse | None:
        """At most ``DIRECT_LIMIT`` unknowns, with a cycle: SCC-wise, else one LU."""
        from veribattery.checker.linalg import scc  # only for a graph with a cycle

        found = scc.components(self.A64)
        if found is not None:
            segmented = scc.segmented_inverse(self.A64, found)
            self._iterative = segmented is not None and segmented.iterative
            if segmented is not None:
                self._segmented = True
                return segmented
        return _lu_inverse(self.A64)

    @property
    def method(self) -> str | None:
        """How the direct solver solves the system, once it is built: ``"substitution"``
        (acyclic), ``"segmented"`` or ``"topological"`` (SCC by SCC), ``"lu"``; None
        when there is none (the iterative fallback) or it is not built yet."""
        if self._direct is None:
            return None
        if isinstance(self._direct, _Triangular):
            return "substitution"
        if isinstance(self._direct, TopologicalSolver):
            return "topological"
        from veribattery.checker.linalg import scc

        return "segmented" if isinstance(self._direct, scc.Segmented) else "lu"

    def _reporting(self, inverse: _Inverse) -> _Inverse:
        """*inverse*, telling the monitor how far each application is when someone
        listens (else *inverse* itself: a short check pays nothing). SCC-wise solvers
        report after each segment; a solve in one call (substitution, LU) before and
        after, so that a long one shows its size."""
        monitor = self.monitor
        if monitor is None or not monitor.heard:
            return inverse
        if isinstance(inverse, TopologicalSolver):
            return functools.partial(inverse.solve, progress=monitor)
        if self._segmented and inverse is self._direct:
            return functools.partial(cast("scc.Segmented", inverse), progress=monitor)
        return functools.partial(_reported, inverse, monitor, self._n)

    def _inverse(self) -> _Inverse | None:
        if not self._direct_tried:
            self._direct_tried = True
            self._direct = self._substitution()
            if self._direct is None and self._n > DIRECT_LIMIT:
                self._direct = _topological_inverse(self.A64)
            elif self._direct is None:
                self._direct = self._factorised()
        return self._direct


def _topological_inverse(A64: sp.csr_matrix) -> TopologicalSolver | None:
    """Above ``DIRECT_LIMIT``: the SCC-by-SCC solve when every component is small enough
    to factorise (at most ``DIRECT_LIMIT`` states), else None (the iterative fallback)."""

    def component(block: sp.csr_matrix) -> _Inverse | None:
        return direct_component(block) if block.shape[0] <= DIRECT_LIMIT else None

    try:
        return TopologicalSolver(A64, component)
    except (CheckError, MemoryError):
        return None


def _reported(inverse: _Inverse, monitor: SolveMonitor, n: int, b: FloatArray) -> FloatArray:
    """``inverse(b)`` of a system of *n* states, reported to *monitor* before and after."""
    monitor(0, n)
    x = inverse(b)
    monitor(n, n)
    return x


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
        out[lo:hi] = csr_rows(A64, lo, hi, np.longdouble) @ x_ext
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
    return compact_solve(lu)


def _converged(correction: FloatArray, x: FloatArray) -> bool:
    """Every correction below REFINE_TOL relative to its component (zero stays zero)."""
    return bool(np.all(np.abs(correction) <= REFINE_TOL * np.abs(x)))
