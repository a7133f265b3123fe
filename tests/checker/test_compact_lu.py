"""A sparse LU kept as its factors (checker/linalg/compact_lu.py).

The solve on the factors must be the solve of the system: checked against the
SuperLU object's own solve and against the exact solution of a small system in
rationals, with row and column permutations (partial pivoting, a fill-reducing order)
and without (the natural order with diagonal pivots). It must not keep the SuperLU
object, whose working memory is what it exists to drop.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from tests.checker import exact_reference as ref
from veribattery.checker.linalg import compact_lu
from veribattery.checker.linalg.compact_lu import compact_solve


def random_system(n: int, seed: int) -> sp.csc_matrix:
    """A nonsingular sparse matrix that needs row exchanges: small diagonal entries
    under larger ones elsewhere in their columns."""
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=4 / n, random_state=rng, format="csc") * 10
    return sp.csc_matrix(A + sp.diags(rng.uniform(0.01, 0.1, n)))


@pytest.mark.parametrize("seed", range(6))
def test_permuted_factors_solve_the_system(seed: int) -> None:
    A = random_system(300, seed)
    lu = spla.splu(A)  # COLAMD and partial pivoting: both permutations move
    assert not np.array_equal(lu.perm_r, np.arange(300))
    assert not np.array_equal(lu.perm_c, np.arange(300))
    solve = compact_solve(lu)
    b = np.random.default_rng(seed + 100).uniform(-1, 1, 300)
    x = solve(b.copy())
    np.testing.assert_allclose(x, lu.solve(b), rtol=1e-9, atol=1e-12)
    scale = np.abs(A) @ np.abs(x) + np.abs(b)
    assert np.all(np.abs(A @ x - b) <= 1e-10 * scale)


def test_natural_order_matches_exact_solution() -> None:
    # An M-matrix in topological order, as the topological solver factorises it.
    A = sp.csc_matrix(np.array([[1.0, 0.0, 0.0, 0.0],
                                [-0.5, 1.0, -0.25, 0.0],
                                [0.0, -0.5, 1.0, 0.0],
                                [-0.125, 0.0, -0.5, 1.0]]))
    lu = spla.splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True})
    assert np.array_equal(lu.perm_r, np.arange(4)) and np.array_equal(lu.perm_c, np.arange(4))
    b = np.array([1.0, 0.0, 0.5, 0.25])
    exact = ref.solve([[Fraction(v) for v in row] for row in A.toarray()],
                      [Fraction(v) for v in b])
    x = compact_solve(lu)(b.copy())
    np.testing.assert_allclose(x, [float(v) for v in exact], rtol=1e-15, atol=0)
    assert exact[1] == Fraction(5, 7)  # (by hand: x1 = 5/8 + x1/8)


def test_the_superlu_object_is_not_kept() -> None:
    if compact_lu._superlu is None:
        pytest.fail("scipy's private triangular solve is gone: the factors are not kept "
                    "alone (compact_lu falls back to the SuperLU object)")
    A = random_system(200, 7)
    lu = spla.splu(A)
    solve = compact_solve(lu)
    kept = [cell.cell_contents for cell in solve.__closure__ or ()]
    assert solve != lu.solve and not any(item is lu for item in kept)
    b = np.ones(200)
    np.testing.assert_allclose(A @ solve(b.copy()), b, atol=1e-9)


def test_falls_back_to_the_superlu_solve_when_the_probe_disagrees(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(compact_lu, "_agrees", False)
    lu = spla.splu(random_system(50, 3))
    solve = compact_solve(lu)
    assert solve == lu.solve


def _triangles_by_operations(lu: spla.SuperLU) -> tuple[sp.csc_matrix, sp.csc_matrix]:
    upper = sp.csc_matrix(lu.U)
    lower = sp.csc_matrix(sp.tril(lu.L, -1, format="csc") + sp.diags(upper.diagonal()))
    return lower, sp.csc_matrix(sp.triu(upper, 1, format="csc"))


@pytest.mark.parametrize("seed", range(40))
def test_triangles_read_off_the_factors_are_those_of_sparse_operations(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 250))
    A = random_system(n, seed) if seed % 2 else sp.csc_matrix(
        sp.eye(n) - 0.9 * sp.random(n, n, density=min(1.0, 3 / n), random_state=rng))
    orders = [{}, {"permc_spec": "NATURAL", "diag_pivot_thresh": 0.0},
              {"permc_spec": "MMD_AT_PLUS_A", "diag_pivot_thresh": 0.0}]
    for options in orders:
        lu = spla.splu(A, **options)  # type: ignore[arg-type]
        for found, expected in zip(compact_lu._triangles(lu), _triangles_by_operations(lu),
                                   strict=True):
            expected.sort_indices()
            assert found.shape == expected.shape
            assert found.indptr.tolist() == expected.indptr.tolist()
            assert found.indices.tolist() == expected.indices.tolist()
            assert found.data.view(np.int64).tolist() == expected.data.view(np.int64).tolist()


def _unit_lower(n: int, seed: int) -> sp.csc_matrix:
    rng = np.random.default_rng(seed)
    strict = sp.tril(sp.random(n, n, density=min(1.0, 3 / n), random_state=rng), -1)
    lower = sp.csc_matrix(strict * -1.0 + sp.eye(n))
    lower.sort_indices()
    return lower


@pytest.mark.parametrize("seed", range(20))
def test_unit_lower_solve_is_spsolve_triangular_bit_for_bit(seed: int) -> None:
    if compact_lu._superlu is None:
        pytest.fail("scipy's private triangular solve is gone (spsolve_triangular is used)")
    n = int(np.random.default_rng(seed).integers(1, 300))
    lower = _unit_lower(n, seed)
    solve = compact_lu.unit_lower_solve(lower.copy())
    assert solve is not None
    b = np.random.default_rng(seed + 1).uniform(0.0, 1.0, n)
    expected = spla.spsolve_triangular(lower.copy(), b.copy(), lower=True, unit_diagonal=True)
    assert solve(b.copy()).view(np.int64).tolist() == expected.view(np.int64).tolist()


def test_unit_lower_solve_steps_aside_when_its_probe_disagrees(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(compact_lu, "_triangular_agrees", False)
    assert compact_lu.unit_lower_solve(_unit_lower(20, 1)) is None


def test_an_ill_conditioned_first_system_keeps_the_compact_solve(
        monkeypatch: pytest.MonkeyPatch) -> None:
    if compact_lu._superlu is None:
        pytest.fail("scipy's private triangular solve is gone (the SuperLU object is kept)")
    monkeypatch.setattr(compact_lu, "_agrees", None)
    # A last column within 1e-6..1e-12 of the sum of the first two: the two solves'
    # summation orders give results more than 1e-9 apart, relative.
    rng = np.random.default_rng(0)
    dense = sp.random(60, 60, density=0.1, random_state=0, format="csc").toarray()
    dense[:, -1] = dense[:, 0] + dense[:, 1] + rng.uniform(-1, 1, 60) * 10.0 ** -rng.integers(
        6, 13)
    lu = spla.splu(sp.csc_matrix(dense))
    probe = np.linspace(1.0, 2.0, 60)
    assert not np.allclose(compact_lu._factors_solve(lu)(probe.copy()), lu.solve(probe),
                           rtol=1e-9, atol=0.0)
    assert compact_solve(lu) != lu.solve
    assert compact_lu._agrees is True
