"""Index work kept by sparsity pattern (linalg.SolverPlans: _RestrictionPlan, _TriangularPlan).

A matrix with the pattern of an earlier one (other probabilities, same transitions)
must get exactly -- bit for bit -- what a fresh computation gives, and the solutions
must match an independent dense solve.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from veribattery.checker import Workspace, kernels, linalg
from veribattery.checker.linalg import restriction, triangular


def _random_chain(rng: np.random.Generator, n: int, acyclic: bool) -> sp.csr_matrix:
    dense = (rng.random((n, n)) < 0.3) * rng.random((n, n))
    if acyclic:  # only moves to higher states, plus self-loops
        dense = np.triu(dense)
    dense[rng.random(n) < 0.2] = 0
    for i in range(n):
        if dense[i].sum() == 0:
            dense[i, i] = 1.0
    dense /= dense.sum(axis=1, keepdims=True)
    return sp.csr_matrix(dense)


def _same(a: sp.spmatrix, b: sp.spmatrix) -> bool:
    a, b = sp.csr_matrix(a), sp.csr_matrix(b)
    return (a.shape == b.shape and np.array_equal(a.indptr, b.indptr)
            and np.array_equal(a.indices, b.indices) and np.array_equal(a.data, b.data))


@pytest.mark.parametrize("seed", range(40))
def test_restriction_plan_equals_a_fresh_computation(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 40))
    P = _random_chain(rng, n, acyclic=bool(seed % 2))
    maybe = rng.random(n) < 0.7
    plans = linalg.SolverPlans()
    for matrix in (P, _reweighted(P, rng), _reweighted(P, rng)):
        planned = linalg.restricted_parts(matrix, maybe, plans)
        fresh = restriction._restricted_parts(matrix, maybe)
        assert all(_same(a, b) for a, b in zip(planned, fresh, strict=True))
    # One pattern: remembered at the first matrix, planned at the second, re-used after.
    assert len(plans.restrictions) == 1
    assert next(iter(plans.restrictions.values())) is not None


@pytest.mark.parametrize("seed", range(40))
def test_diagonal_slotted_into_sorted_rows_equals_sorting(seed: int) -> None:
    """Rows of P in column order: the diagonal is put in its place instead of every
    row being sorted; the same arrays bit for bit, and the matrix is I - P restricted."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 60))
    P = _random_chain(rng, n, acyclic=bool(seed % 2))
    maybe = rng.random(n) < 0.7
    idx = np.flatnonzero(maybe)
    slotted = restriction._restricted_parts(P, maybe)[0]
    unsorted = P.copy()
    unsorted.has_sorted_indices = False  # as if unknown: the sorting path
    for i in range(n):  # reverse each row's entries, so that a sort is needed
        lo, hi = unsorted.indptr[i], unsorted.indptr[i + 1]
        unsorted.indices[lo:hi] = unsorted.indices[lo:hi][::-1].copy()
        unsorted.data[lo:hi] = unsorted.data[lo:hi][::-1].copy()
    assert not unsorted.has_sorted_indices
    assert _same(slotted, restriction._restricted_parts(unsorted, maybe)[0])
    assert slotted.has_sorted_indices
    expected = np.eye(idx.size) - P.toarray()[np.ix_(idx, idx)]
    np.testing.assert_allclose(slotted.toarray(), expected, rtol=0, atol=1e-15)


@pytest.mark.parametrize("seed", range(60))
def test_sorted_rows_path_equals_the_general_one_bit_for_bit(seed: int) -> None:
    """``_sorted_system`` (rows in column order: the diagonal slotted in, no scatter)
    against ``_row_sums`` and ``_with_diagonal`` (any order) on the same rows: the same
    matrix and the same extended-precision leaving probabilities, bit for bit (numpy
    pairs a reduction's terms by position, so the segments must be the same)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 120))
    # Long rows with a self-loop among their entries: the self-loop is no mover, and
    # the sums of the movers around it are where a different pairing would show.
    dense = (rng.random((n, n)) < 0.5) * rng.random((n, n))
    np.fill_diagonal(dense, rng.random(n) * (rng.random(n) < 0.8))
    dense[dense.sum(axis=1) == 0, 0] = 1.0
    P = sp.csr_matrix(dense / dense.sum(axis=1, keepdims=True))
    if seed % 3 == 0:  # stored zeros, dropped from the matrix
        P.data[rng.random(P.nnz) < 0.2] = 0.0
    maybe = rng.random(n) < 0.7
    idx = np.flatnonzero(maybe)
    rows = sp.csr_matrix(P[idx])
    position = np.full(n, -1, dtype=np.int32)
    position[idx] = np.arange(idx.size, dtype=np.int32)
    row_of = np.repeat(np.arange(idx.size, dtype=np.int32), np.diff(rows.indptr))
    column = position[rows.indices]
    moves = column != row_of
    A64, leave, leave64 = restriction._sorted_system(rows, row_of, column, moves, np.int32)
    general_leave = restriction._row_sums(row_of[moves], rows.data[moves], idx.size)
    keep = moves & (column >= 0) & (rows.data != 0)
    general = restriction._with_diagonal(row_of[keep], column[keep], -rows.data[keep],
                                         general_leave.astype(np.float64))
    assert np.array_equal(leave, general_leave) and leave.dtype == np.longdouble
    assert np.array_equal(leave64, general_leave.astype(np.float64))
    assert _same(A64, general) and A64.has_sorted_indices


def _reweighted(P: sp.csr_matrix, rng: np.random.Generator) -> sp.csr_matrix:
    """Same positions, other probabilities (rows renormalised)."""
    Q = P.copy()
    Q.data = Q.data * rng.uniform(0.5, 1.5, Q.data.size)
    sums = np.asarray(Q.sum(axis=1)).ravel()
    R = sp.csr_matrix(sp.diags(1.0 / sums) @ Q)
    R.sum_duplicates()  # canonical, as the builder's matrices are
    return R


@pytest.mark.parametrize("seed", range(12))
def test_triangular_plan_solves_reweighted_matrices(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(3, 30))
    P = _random_chain(rng, n, acyclic=True)
    target = np.zeros(n, dtype=bool)
    target[n - 1] = True
    workspace = Workspace()
    for matrix in (P, _reweighted(P, rng)):
        maybe = ~target & ~kernels.prob0(matrix, np.ones(n, dtype=bool), target,
                                         workspace=workspace)
        if not maybe.any():
            continue
        A64, _, rows = linalg.restricted_parts(matrix, maybe, workspace.solvers)
        inverse = triangular._triangular_inverse(A64, workspace.solvers)
        assert inverse is not None
        b = np.asarray(rows @ target.astype(np.float64))
        exact = np.linalg.solve(A64.toarray(), b)
        assert np.allclose(inverse(b), exact, rtol=1e-12, atol=1e-15)


def test_index_digest_is_memoised_by_identity_and_follows_content() -> None:
    rng = np.random.default_rng(7)
    P = _random_chain(rng, 12, acyclic=False)
    plans = linalg.SolverPlans()
    first = linalg.index_digest(P.indptr, P.indices, plans)
    assert linalg.index_digest(P.indptr, P.indices, plans) == first
    assert len(plans.digests) == 1
    # Equal arrays that are other objects: the same digest, computed again.
    assert linalg.index_digest(P.indptr.copy(), P.indices.copy(), plans) == first
    assert linalg.index_digest(P.indptr.copy(), P.indices.copy()) == first  # nothing kept
    other = P.indices.copy()
    other[0] = (other[0] + 1) % P.shape[1]
    assert linalg.index_digest(P.indptr, other, plans) != first
