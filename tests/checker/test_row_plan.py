"""AffineMap.of keeps the index work of a pattern seen twice (a structure-reusing sweep)
and gives, with or without it, the map of the documented formulas bit for bit."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from veribattery.checker import certify
from veribattery.checker.certify.rounding import TERM_FLOOR, enclose_product, error_coefficient


def _rows(seed: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """Rows P[states, :] of a random stochastic matrix, self-loops included."""
    rng = np.random.default_rng(seed)
    n = 400
    P = sp.random(n, n, density=0.02, random_state=seed, format="csr") + sp.eye(n) * 0.3
    P = sp.csr_matrix(P)
    P.data = rng.random(P.nnz) + 0.01
    P = sp.csr_matrix(P.multiply(1 / np.asarray(P.sum(axis=1)).ravel()[:, None]))
    states = np.flatnonzero(rng.random(n) < 0.6)
    return sp.csr_matrix(P[states]), states


def _reference(rows: sp.csr_matrix, states: np.ndarray) -> dict[str, np.ndarray]:
    """The map's row data from the formulas: off-diagonal rows, enclosed row sums."""
    dense = rows.toarray()
    dense[np.arange(states.size), states] = 0.0
    mask = rows.copy()
    mask.data = np.ones(mask.nnz)
    mask[np.arange(states.size), states] = 0.0  # (structurally: entries of the diagonal)
    off = sp.csr_matrix(rows.multiply(mask))
    off.eliminate_zeros()
    _, low, high = enclose_product(off, np.ones(rows.shape[1]))
    terms = np.diff(off.indptr).astype(np.float64)
    return {"data": off.data, "indices": off.indices, "indptr": off.indptr, "dense": dense,
            "leave_lower": np.maximum(low, 0.0), "leave_upper": high, "terms": terms,
            "coefficient": error_coefficient(terms + 1.0),
            "underflow": (terms + 1.0) * TERM_FLOOR}


def _assert_is(F: certify.AffineMap, expected: dict[str, np.ndarray]) -> None:
    assert np.array_equal(F.rows.toarray(), expected["dense"])
    for name in ("data", "indices", "indptr"):
        assert np.array_equal(getattr(F.rows, name), expected[name]), name
    for name in ("leave_lower", "leave_upper", "terms", "coefficient", "underflow"):
        assert np.array_equal(getattr(F, name), expected[name]), name


@pytest.mark.parametrize("seed", range(3))
def test_planned_maps_equal_the_formulas_across_values(seed: int) -> None:
    rows, states = _rows(seed)
    zeros = np.zeros(rows.shape[1])
    plans = certify.RowPlans()
    for point in range(4):  # the same pattern, new probabilities at every point
        values = rows.copy()
        values.data = rows.data * (1 + point / 7)
        F = certify.AffineMap.of(values, states, zeros, zeros, None, plans=plans)
        _assert_is(F, _reference(values, states))
    assert plans.plans and plans.plans[0].fits(rows, states)
    assert not plans.plans[0].indices.flags.writeable


def test_another_pattern_of_the_same_shape_is_not_planned_as_the_kept_one() -> None:
    rows, states = _rows(5)
    zeros = np.zeros(rows.shape[1])
    plans = certify.RowPlans()
    for _ in range(2):
        certify.AffineMap.of(rows, states, zeros, zeros, None, plans=plans)
    moved = rows.copy()
    moved.indices = moved.indices.copy()
    row = int(np.flatnonzero(np.diff(moved.indptr) > 1)[0])
    start = moved.indptr[row]
    moved.indices[start], moved.indices[start + 1] = (
        moved.indices[start + 1], moved.indices[start])  # same shape, other order
    assert not plans.plans[0].fits(moved, states)
    F = certify.AffineMap.of(moved, states, zeros, zeros, None, plans=plans)
    expected = _reference(moved, states)  # (sorted: sums in another order, same terms)
    assert np.array_equal(F.rows.toarray(), expected["dense"])
    assert np.array_equal(F.terms, expected["terms"])
    for i, row in enumerate(expected["dense"]):
        exact = sum(Fraction(float(v)) for v in row)
        assert Fraction(F.leave_lower[i]) <= exact <= Fraction(F.leave_upper[i])


def test_a_sweep_points_two_systems_keep_their_plans() -> None:
    first, second = _rows(7), _rows(8)
    plans = certify.RowPlans()
    for _ in range(3):  # each point: the reward system's map, then the recharge cap's
        for rows, states in (first, second):
            zeros = np.zeros(rows.shape[1])
            certify.AffineMap.of(rows, states, zeros, zeros, None, plans=plans)
    assert len(plans.plans) == 2
    assert {id(p) for p in plans.plans} == {
        id(next(p for p in plans.plans if p.fits(*pair))) for pair in (first, second)}
    # Without plans nothing is kept, and the maps are the same.
    rows, states = first
    zeros = np.zeros(rows.shape[1])
    _assert_is(certify.AffineMap.of(rows, states, zeros, zeros, None), _reference(rows, states))
