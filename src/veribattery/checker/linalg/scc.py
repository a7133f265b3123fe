"""SCC-wise solving of ``A x = b`` for any component size, in bounded memory.

``A = I - P_mm`` restricted to the unknown states. Permuted into a topological
order of its strongly connected components (successors first), *A* is block
lower triangular, so the system is solved segment by segment: a *segment* is
either one large component (more than ``BLOCK_LIMIT`` states, or dense) or a
maximal run of small ones. Segment ``s`` on positions ``[lo, hi)`` solves

    A[s, s] x_s = b_s - A[s, :lo] x[:lo]

once every earlier segment is known. The method per segment is chosen by its size:

* a *dense* component (``DENSE_MIN`` states or more, on average ``DENSE_DEGREE``
  or more entries per row inside it, as in Herman's self-stabilising ring):
  Jacobi-preconditioned BiCGSTAB/GMRES, whose few dozen steps cost far less
  than an LU that fills in like a dense matrix; its LU only where the
  iteration falls short;
* a run of small components: SuperLU in the natural (topological) order with
  diagonal pivots, so the fill-in stays inside each component (the component
  by component solve, done in C);
* a larger component whose LU factors are cheap -- at most ``LU_LIMIT`` states,
  or any size when the envelope of its reverse Cuthill-McKee order (an upper
  bound of the factors of a profile factorisation) has at most ``ENVELOPE_LIMIT``
  entries, as on chains, rings and thin bands: SuperLU with a
  fill-reducing ordering (minimum degree on ``A + A^T``), diagonal pivots (safe:
  ``A`` is a nonsingular M-matrix);
* any other component (a 2-D or 3-D mesh of 10^5 states or more, whose LU fill
  grows like ``n log n`` or ``n^(4/3)`` with a large constant: 2 GB at 10^6
  states): BiCGSTAB, then restarted GMRES, preconditioned by one V-cycle of
  classical (Ruge-Stueben) algebraic multigrid (pyamg), which suits M-matrices
  and keeps memory linear in the component (about three times its nonzeros);
  an incomplete LU with capped fill, then Jacobi, when the multigrid set-up fails.

The result is only an approximate inverse: :mod:`~veribattery.checker.linalg.factorization`
judges every solution by its backward-error rule and ``certify`` bounds the
error rigorously, so no method here needs to be exact to keep results certified.
"""

from __future__ import annotations

import hashlib
import itertools
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.sparse import linalg as spla

from veribattery._types import FloatArray
from veribattery.checker.linalg.topological import Inverse, Progress, superlu

#: Components up to this size are solved together with their neighbours in runs.
BLOCK_LIMIT = 4_096
#: A run of small components is factorised in pieces of about this many states.
RUN_LIMIT = 65_536
#: Components up to this size get a sparse LU with a fill-reducing order; larger
#: ones only when their envelope is small (below). On the 10^6-state grid walk
#: (one component) the LU took 101 s and 2.0 GB, multigrid-preconditioned
#: BiCGSTAB a few times less of both (the measurement is in the git history).
LU_LIMIT = 200_000
#: A larger component still gets the LU when the envelope of its reverse
#: Cuthill-McKee order (which bounds the factors' entries in that order) is at
#: most this: about 300 MB of factors at 12 bytes an entry.
ENVELOPE_LIMIT = 25_000_000
#: A component of at least DENSE_MIN states whose states have on average at least
#: DENSE_DEGREE successors inside it (Herman's ring: hundreds) is dense: its LU
#: fills in like a dense matrix (minutes and gigabytes at 10^4 states), while
#: such well-mixing chains converge in tens of Jacobi-preconditioned Krylov steps
#: (with the LU as the fallback should they not).
DENSE_MIN = 512
DENSE_DEGREE = 16
#: Incomplete LU of a larger component: drop tolerance and fill cap (x its nonzeros).
ILU_DROP = 1e-4
ILU_FILL = 4.0
#: Krylov tolerance and iteration cap inside a large component.
KRYLOV_RTOL = 1e-12
KRYLOV_MAXITER = 2_000
#: Krylov tolerance of a certificate's margin ``A^-1 d`` (:meth:`Segmented.margin`):
#: the margin only has to over-cover the defect componentwise, so a few digits do.
MARGIN_RTOL = 1e-6
#: ... whose right-hand side is first lifted to at least this fraction of its
#: largest entry, so that a normwise tolerance is also a componentwise one.
MARGIN_FLOOR = 1e-3

#: Applies an approximate inverse of a matrix to a float64 vector.
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class Components:
    """The states in a topological order of the SCCs (successors first).

    :param order: ``order[k]`` is the state at position *k*.
    :param starts: the first position of every component, then ``n``.
    :param inner: the number of matrix entries inside each component.
    """

    order: IntArray
    starts: IntArray
    inner: IntArray

    @property
    def largest(self) -> int:
        """The size of the largest component (0 when there are none)."""
        return int(np.diff(self.starts).max(initial=0))


def components(A64: sp.csr_matrix) -> Components | None:
    """The SCCs of *A64*'s graph in topological order, or None if scipy's
    labelling is not topological (checked against every edge between components).
    """
    count, labels = csgraph.connected_components(A64, directed=True, connection="strong")
    coo = A64.tocoo()
    src, dst = labels[coo.row], labels[coo.col]
    across = src != dst
    if np.all(dst[across] < src[across]):
        key = labels
    elif np.all(dst[across] > src[across]):
        key = count - 1 - labels
    else:
        return None
    order = np.argsort(key, kind="stable").astype(np.int64)
    sizes = np.bincount(key, minlength=count)
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    inner = np.bincount(key[coo.row[~across]], minlength=count).astype(np.int64)
    return Components(order, starts, inner)


def segments(found: Components) -> list[tuple[int, int, bool]]:
    """``(lo, hi, large)`` position ranges: each large (or :func:`dense`) component
    alone, small ones in runs."""
    sizes = np.diff(found.starts)
    large = np.flatnonzero((sizes > BLOCK_LIMIT) | dense(sizes, found.inner))
    cuts = np.unique(np.concatenate([found.starts[[0, -1]], found.starts[large],
                                     found.starts[large + 1]]))
    alone = set(found.starts[large].tolist())
    result = []
    for lo, hi in itertools.pairwise(cuts.tolist()):
        if lo in alone:
            result.append((int(lo), int(hi), True))
        else:
            result.extend((a, b, False) for a, b in _run_pieces(found.starts, lo, hi))
    return result


def _run_pieces(starts: IntArray, lo: int, hi: int) -> list[tuple[int, int]]:
    """A run of small components ``[lo, hi)`` cut at component starts into pieces of
    about :data:`RUN_LIMIT` states: SuperLU's workspace grows with the matrix it
    factors (250 MB above its factors on a run of 488,853 states), a piece's does
    not, and the pieces are solved one after the other like any segments."""
    if hi - lo <= RUN_LIMIT:
        return [(lo, hi)]
    inside = starts[(starts > lo) & (starts < hi)]
    wanted = np.arange(lo + RUN_LIMIT, hi, RUN_LIMIT)
    chosen = np.unique(inside[np.minimum(np.searchsorted(inside, wanted), inside.size - 1)])
    bounds = [lo, *(int(c) for c in chosen), hi]
    return list(itertools.pairwise(bounds))


@dataclass(frozen=True, slots=True)
class Segmented:
    """Block forward substitution over the segments (see :func:`segmented_inverse`).

    :param order: the states in topological order of their components.
    :param parts: per segment ``(lo, hi, coupling, solver)``: its positions, its rows
        of the permuted matrix in the columns before *lo* (renumbered) and its
        diagonal block's solver.
    :param iterative: whether some segment is solved by a Krylov method (each
        application is then a full iterative solve, not a pair of substitutions).
    """

    order: IntArray
    parts: tuple[tuple[int, int, sp.csr_matrix, Inverse], ...]
    iterative: bool
    #: The last right-hand side's digest and solution, with a Krylov segment: the
    #: quick path's solve and the refined path's first step are then one solve.
    last: dict[bytes, FloatArray] = field(default_factory=dict)

    def __call__(self, b: FloatArray, progress: Progress | None = None) -> FloatArray:
        """``A^-1 b`` approximately.

        :param progress: told the states solved so far after each segment.
        """
        if not self.iterative:
            return self._apply(b, KRYLOV_RTOL, progress)
        key = hashlib.blake2b(np.ascontiguousarray(b, dtype=np.float64).data,
                              digest_size=20).digest()
        if key not in self.last:
            self.last.clear()
            self.last[key] = self._apply(b, KRYLOV_RTOL, progress)
        return self.last[key].copy()

    def margin(self, v: FloatArray) -> FloatArray:
        """An approximate ``A^-1 v'`` with ``v' >= v`` for a certificate's margin.

        With a Krylov segment, *v* is lifted to ``MARGIN_FLOOR * max(v)`` and the
        Krylov solves stop at ``MARGIN_RTOL``: the certificate's test, not this
        solve, decides whether the margin covers the defect.
        """
        if not self.iterative:
            return self._apply(v, KRYLOV_RTOL)
        lifted = np.maximum(v, MARGIN_FLOOR * float(np.max(v, initial=0.0)))
        return self._apply(lifted, MARGIN_RTOL)

    def _apply(self, b: FloatArray, rtol: float, progress: Progress | None = None) -> FloatArray:
        order = self.order
        y = np.zeros(order.size, dtype=np.float64)
        permuted_b = np.asarray(b, dtype=np.float64)[order]
        for lo, hi, rows, solver in self.parts:
            rhs = np.ascontiguousarray(permuted_b[lo:hi] - rows @ y[:lo] if lo
                                       else permuted_b[lo:hi])
            y[lo:hi] = solver.solve(rhs, rtol) if isinstance(solver, _Krylov) else solver(rhs)
            if progress is not None:
                progress(hi, order.size)
        x = np.empty_like(y)
        x[order] = y
        return x


def segmented_inverse(A64: sp.csr_matrix, found: Components) -> Segmented | None:
    """Block forward substitution over the segments of *found* (None if a block fails)."""
    order = found.order
    position = np.empty_like(order)
    position[order] = np.arange(order.size)
    parts: list[tuple[int, int, sp.csr_matrix, Inverse]] = []
    iterative = False
    identity = bool(np.all(order == np.arange(order.size)))
    for lo, hi, large in segments(found):
        if identity and (lo, hi) == (0, order.size):
            rows = block = A64  # one component in its own order: no copy (10^6 states: 60 MB)
        else:
            rows = sp.csr_matrix(A64[order[lo:hi]])  # a copy: renumbering its columns is safe
            rows.indices = position[rows.indices].astype(rows.indices.dtype)
            rows.has_sorted_indices = False
            block = rows if (lo, hi) == (0, order.size) else sp.csr_matrix(rows[:, lo:hi])
        solver = _block_solver(block, large=large)
        if solver is None:
            return None
        del block
        iterative = iterative or isinstance(solver, _Krylov)
        parts.append((lo, hi, _coupling(rows, lo), solver))
    return Segmented(order, tuple(parts), iterative)


def _coupling(rows: sp.csr_matrix, lo: int) -> sp.csr_matrix:
    """The entries of a segment's *rows* in columns before *lo*: all that ``rows @ y``
    reads while ``y`` is still 0 from *lo* on (the diagonal block is in its solver).
    The same sums in the same order, without a second copy of the block's entries."""
    return sp.csr_matrix(rows[:, :lo]) if lo else sp.csr_matrix((rows.shape[0], 0))


def dense(sizes: IntArray, inner: IntArray) -> npt.NDArray[np.bool_]:
    """Which components (of *sizes* states and *inner* entries) are dense."""
    return (sizes >= DENSE_MIN) & (inner >= DENSE_DEGREE * sizes)


def _block_solver(block: sp.csr_matrix, *, large: bool) -> Inverse | None:
    """The solver of one segment's diagonal block, chosen by its estimated LU memory."""
    if not large:
        return superlu(block, "NATURAL")
    size = np.array([block.shape[0]])
    if dense(size, np.array([block.nnz]))[0]:
        return _KrylovFirst(krylov_solver(block, _jacobi(block)), block)
    if block.shape[0] <= LU_LIMIT or _thin(block):
        return superlu(block, "MMD_AT_PLUS_A") or krylov_solver(block)
    return krylov_solver(block)


def _thin(block: sp.csr_matrix) -> bool:
    """Whether *block*'s LU factors are small for sure: the envelope (profile) of
    its reverse Cuthill-McKee order, which bounds the entries of an LU in that
    order, is at most ``ENVELOPE_LIMIT`` (the minimum-degree order does no worse
    in practice). Linear in the size of the block."""
    pattern = sp.csr_matrix(block, copy=True)
    pattern.data = np.ones_like(pattern.data)
    symmetric = sp.csr_matrix(pattern + pattern.T)
    del pattern
    order = csgraph.reverse_cuthill_mckee(symmetric, symmetric_mode=True)
    position = np.empty_like(order)
    position[order] = np.arange(order.size, dtype=order.dtype)
    # Every row holds its diagonal (A is an M-matrix), so no row is empty.
    lowest = np.minimum.reduceat(position[symmetric.indices], symmetric.indptr[:-1])
    envelope = int(np.sum(position - lowest, dtype=np.int64))
    return bool(2 * envelope + block.shape[0] <= ENVELOPE_LIMIT)


def _preconditioner(block: sp.csr_matrix) -> spla.LinearOperator:
    """One V-cycle of classical AMG; incomplete LU with capped fill if that cannot be
    set up; Jacobi when neither can."""
    try:
        import pyamg  # a second or so to import: only for components this large

        hierarchy = pyamg.ruge_stuben_solver(sp.csr_matrix(block))
        return hierarchy.aspreconditioner(cycle="V")
    except (ValueError, RuntimeError, MemoryError, np.linalg.LinAlgError):
        pass
    try:
        ilu = spla.spilu(sp.csc_matrix(block), drop_tol=ILU_DROP, fill_factor=ILU_FILL,
                         permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0)
        return spla.LinearOperator(block.shape, matvec=ilu.solve)
    except (RuntimeError, MemoryError):
        return _jacobi(block)


def _jacobi(block: sp.csr_matrix) -> spla.LinearOperator:
    """Division by the diagonal (positive: *block* is an M-matrix)."""
    inverse_diagonal = 1.0 / block.diagonal()
    return spla.LinearOperator(block.shape, matvec=lambda v: inverse_diagonal * v)


@dataclass(frozen=True, slots=True)
class _Krylov:
    """Preconditioned BiCGSTAB, then restarted GMRES when BiCGSTAB stalls.

    Each call solves to ``KRYLOV_RTOL``; a failure shows as a poor answer, which
    the caller's backward-error rule rejects.
    """

    A: sp.csr_matrix
    M: spla.LinearOperator

    def __call__(self, b: FloatArray) -> FloatArray:
        return self.solve(b, KRYLOV_RTOL)

    def solve(self, b: FloatArray, rtol: float) -> FloatArray:
        """``A^-1 b`` to the relative (2-norm) residual *rtol*."""
        if not b.any():
            return np.zeros_like(b)
        A = self.A
        options = {"rtol": rtol, "atol": 0.0, "M": self.M}
        with np.errstate(all="ignore"):
            x, info = spla.bicgstab(A, b, maxiter=KRYLOV_MAXITER, **options)
            if info != 0 or not np.all(np.isfinite(x)):
                start = x if np.all(np.isfinite(x)) else None
                x, _ = spla.gmres(A, b, x0=start, restart=min(A.shape[0], 60),
                                  maxiter=max(1, KRYLOV_MAXITER // 60), **options)
        return np.asarray(x, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class _KrylovFirst:
    """Krylov iteration on a dense component, and its LU (made once) wherever the
    iteration does not reach ``KRYLOV_RTOL``."""

    krylov: Inverse
    block: sp.csr_matrix
    lu: list[Inverse | None] = field(default_factory=list)

    def __call__(self, b: FloatArray) -> FloatArray:
        x = self.krylov(b)
        scale = float(np.max(np.abs(b), initial=0.0))
        residual = float(np.max(np.abs(b - self.block @ x), initial=0.0))
        if np.all(np.isfinite(x)) and residual <= 100 * KRYLOV_RTOL * scale:
            return x
        if not self.lu:
            self.lu.append(superlu(self.block, "MMD_AT_PLUS_A"))
        solve = self.lu[0]
        return x if solve is None else np.asarray(solve(b), dtype=np.float64)


def krylov_solver(block: sp.csr_matrix,
                  preconditioner: spla.LinearOperator | None = None) -> Inverse:
    """The Krylov solver of *block* (see :class:`_Krylov`) with *preconditioner*
    (default: :func:`_preconditioner`'s multigrid)."""
    return _Krylov(sp.csr_matrix(block), preconditioner or _preconditioner(block))
