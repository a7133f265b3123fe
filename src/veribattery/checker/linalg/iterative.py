"""Backward error and the iterative fallback of the linear solves.

:func:`backward_error` is the acceptance rule of every solve (normwise, residual in
extended precision); :func:`solve_iterative` (Jacobi-preconditioned BiCGSTAB, then
restarted GMRES) is the fallback when no direct solver is available.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse import linalg as spla

from veribattery._types import FloatArray

if TYPE_CHECKING:
    from veribattery.checker.linalg.monitor import SolveListener
    from veribattery.checker.linalg.restriction import ExtArray


#: Accept a solution whose normwise backward error is at most this.
RESIDUAL_TOL = 1e-10
#: Relative tolerance handed to BiCGSTAB and GMRES.
ITERATIVE_RTOL = 1e-13
#: Iteration cap of each iterative method.
ITERATIVE_MAXITER = 20_000
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
    # Rounding to float64 first gives the same float (rounding is monotone and odd) at a
    # tenth of the cost: reductions over long doubles run without SIMD.
    return float(np.max(np.abs(np.asarray(v, dtype=np.float64)), initial=0.0))


def solve_iterative(A: sp.csr_matrix, b: FloatArray, x0: FloatArray | None,
                    progress: SolveListener | None = None) -> FloatArray:
    """BiCGSTAB, then restarted GMRES if BiCGSTAB breaks down; Jacobi-preconditioned.

    Both start from *x0* when it is finite (a rejected LU answer is still a good guess).

    :param progress: told ``(iterations, cap, "iterations")`` after each iteration
        (the callback reads no iterate: the iterations are the same with or without it).
    """
    # A breakdown shows up as overflow inside BiCGSTAB or GMRES, and so does a solution
    # beyond the largest double (an expected reward of 1e308 per step); the result is
    # judged by the backward-error rule, so the floating-point warnings carry no news.
    with np.errstate(all="ignore"):
        return _iterated(A, b, x0, progress)


def _iterated(A: sp.csr_matrix, b: FloatArray, x0: FloatArray | None,
              progress: SolveListener | None) -> FloatArray:
    x = x0 if x0 is not None and np.all(np.isfinite(x0)) else np.zeros_like(b)
    inverse_diagonal = 1.0 / A.diagonal()
    jacobi = spla.LinearOperator(A.shape, matvec=lambda v: inverse_diagonal * v)
    options = {"rtol": ITERATIVE_RTOL, "atol": 0.0, "M": jacobi}
    candidate, _ = spla.bicgstab(A, b, x0=x, maxiter=ITERATIVE_MAXITER,
                                 callback=_counter(progress, ITERATIVE_MAXITER), **options)
    if np.all(np.isfinite(candidate)):
        x = candidate
    if backward_error(A, x, b.astype(np.longdouble)) > RESIDUAL_TOL:
        restart = min(A.shape[0], 60)
        # GMRES counts restart cycles, so the cap is in inner iterations as well.
        # callback_type "pr_norm": a call per inner iteration, the cap still in cycles.
        x, _ = spla.gmres(A, b, x0=x, restart=restart,
                          maxiter=max(1, ITERATIVE_MAXITER // restart),
                          callback=_counter(progress, ITERATIVE_MAXITER),
                          callback_type="pr_norm", **options)
    return np.asarray(x, dtype=np.float64)


def _counter(progress: SolveListener | None, cap: int) -> Callable[[object], None] | None:
    """A scipy callback that tells *progress* the iterations so far (None: no callback)."""
    if progress is None:
        return None
    done = itertools.count(1)

    def told(_: object) -> None:
        progress(next(done), cap, "iterations")

    return told
