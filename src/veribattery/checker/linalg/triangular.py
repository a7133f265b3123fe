"""Triangular systems: substitution plans and the substitution solve.

A restricted system whose matrix is triangular in some order (an acyclic chain) is
solved by one forward substitution after a symmetric permutation; the permutation
and the index work are planned once per sparsity pattern and kept in
:class:`~veribattery.checker.linalg.restriction.SolverPlans`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.sparse import linalg as spla

from veribattery._memory import TRIM_MIN_STATES
from veribattery._sparse import csc_sharing
from veribattery._types import BoolArray, FloatArray
from veribattery.checker.linalg.restriction import RESTRICTIONS_KEPT, index_digest

if TYPE_CHECKING:
    from veribattery.checker.linalg.factorization import _Inverse
    from veribattery.checker.linalg.restriction import SolverPlans


try:  # SuperLU's triangular solve, used by _substitution when it behaves as expected
    from scipy.sparse.linalg._dsolve import _superlu
except ImportError:  # pragma: no cover -- scipy moved it: the public path is used
    _superlu = None
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


#: Substitution plans a :class:`SolverPlans` keeps: those of the last few patterns.
PLANS_KEPT = 4


def _pattern_digest(A64: sp.csr_matrix, plans: SolverPlans) -> bytes:
    """A digest of *A64*'s shape and stored positions (not its values)."""
    digest = hashlib.blake2b(digest_size=20)
    digest.update(np.asarray(A64.shape, dtype=np.int64).tobytes())
    digest.update(index_digest(A64.indptr, A64.indices, plans))
    return digest.digest()


def _triangular_plan(A64: sp.csr_matrix, plans: SolverPlans | None) -> _TriangularPlan | None:
    """The plan of *A64*'s pattern (None if its graph has a cycle), kept in *plans* by
    pattern when that is seen a second time."""
    A64.sum_duplicates()  # canonical: one stored entry per position
    if plans is None:
        return _new_plan(A64)
    key = _pattern_digest(A64, plans)
    kept, seen = plans.triangular, plans.triangular_seen
    if key in kept:
        kept.move_to_end(key)
        return kept[key]
    plan = _new_plan(A64)
    if plan is not None and key not in seen:
        seen[key] = None
        while len(seen) > RESTRICTIONS_KEPT:
            seen.popitem(last=False)
        return plan
    seen.pop(key, None)
    kept[key] = plan
    while len(kept) > PLANS_KEPT:
        kept.popitem(last=False)
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


def _triangular_inverse(A64: sp.csr_matrix, plans: SolverPlans | None = None
                        ) -> _Triangular | None:
    """Substitution in a topological order of *A64*'s graph; None if that has a cycle.

    The permutation and the triangular matrix's structure come from the pattern's
    plan (:func:`_triangular_plan`, shared by matrices of one pattern); the values
    are gathered from *A64*: a state's successors precede it, so the permuted
    matrix is lower triangular.
    """
    plan = _triangular_plan(A64, plans)
    if plan is None:
        return None
    diagonal = np.asarray(A64.data[plan.diagonal_at], dtype=np.float64)
    if not np.all(diagonal > 0):
        return None
    # Columns scaled to a unit diagonal: L y = b, then x = y / diagonal (each
    # column's scale repeated over its entries: no per-entry index array). A
    # subnormal diagonal overflows the scale: the solution is then not finite, and
    # is rejected as such, so the overflow needs no warning.
    data = A64.data[plan.gather]
    with np.errstate(over="ignore", invalid="ignore"):
        scale = 1.0 / diagonal
        data *= np.repeat(scale, np.diff(plan.indptr))
    n = A64.shape[0]
    lower = csc_sharing(data, plan.indices, plan.indptr, (n, n))
    return _Triangular(lower, plan.order, scale, plans)


class _Triangular:
    """The substitution of :func:`_triangular_inverse`: ``A x = b`` with ``A = L D`` in
    a topological order (``L`` unit lower triangular, ``D`` the diagonal of *A*)."""

    def __init__(self, lower: sp.csc_matrix, order: npt.NDArray[np.integer],
                 scale: FloatArray, plans: SolverPlans | None) -> None:
        self._lower, self._order, self._scale, self._plans = lower, order, scale, plans
        self._substitute = _substitution(lower, plans=plans)
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
        """The answer of the substitution's *y* (scaled in place) in state order; beyond
        the largest double it is infinite, which its callers reject or certify."""
        with np.errstate(over="ignore", invalid="ignore"):
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
            self._transposed = _substitution(self._lower, transposed=True, plans=self._plans)
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
                                                 shape=lower.shape), plans=self._plans)
        where = np.flatnonzero(mask)

        def apply(b: FloatArray) -> FloatArray:
            c = self._to_order(b)
            c[at] /= scale[at]  # y_i = d_i b_i, so that x_i = y_i / d_i is b_i
            x = self._from_order(substitute(c))
            x[where] = b[where]
            return x

        return apply


def _substitution(lower: sp.csc_matrix, *, transposed: bool = False,
                  plans: SolverPlans | None = None) -> _Inverse:
    """Forward substitution with the unit lower-triangular CSC matrix *lower* (with
    *transposed*, backward substitution with its transpose; the returned function may
    overwrite its argument with the solution).

    SuperLU's triangular solve on prepared arrays (what ``spsolve_triangular``
    calls after copying and rescaling its argument each time); the public
    function is the fallback should that private entry point change. Whether it
    behaves as expected is probed once per mode and *plans* (every time without).
    """
    checked = plans.private_modes if plans is not None else set()
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
        if trans in checked:
            return private
        probe = private(np.ones(n, dtype=np.float64))
        product = lower.T @ probe if transposed else lower @ probe
        if np.all(np.isfinite(probe)) and np.allclose(product, 1.0):
            checked.add(trans)
            return private
    except Exception:
        pass
    return public
