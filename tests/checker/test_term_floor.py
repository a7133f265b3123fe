"""AffineMap's per-term underflow allowance is a normal number (certify.TERM_FLOOR): images
of rows whose numerator is exactly 0 stay off subnormals, and the bounds still enclose
the exact values (solved here in rationals)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import scipy.sparse as sp

from veribattery.checker import Workspace, certify, kernels

TINY = np.finfo(np.float64).tiny  # the smallest normal float64


def test_underflow_allowance_is_normal_and_covers_the_products() -> None:
    rows = sp.csr_matrix(np.array([[0.5, 0.25, 0.25], [0.0, 0.0, 1.0]]))
    F = certify.AffineMap.of(rows, np.array([0, 1]), np.zeros(3), np.zeros(3), None)
    assert np.all(F.underflow >= 2 * (F.terms + 1) * certify.ETA)  # the underflow bound
    assert np.all(F.underflow >= TINY)
    low, high = F.images(np.zeros(2), np.zeros(2))
    assert np.all(low == 0.0)
    assert np.all((high > 0) & (high >= TINY) & (high < 1e-250))  # normal, and tiny


def _chain() -> tuple[sp.csr_matrix, list[list[Fraction]]]:
    """States 0..5: 0 -> 1 (1/3), 2 (1/3), 3 (1/3); 1 -> 4 (1/2), 0 (1/4), 1 (1/4);
    2 -> 3 (1/2), 5 (1/2); 3 -> 3 (1/2), 5 (1/2); 4 (target) and 5 (sink) absorbing.
    2 and 3 cannot reach 4 (value exactly 0) but reach 5 almost surely."""
    third, half, quarter = Fraction(1, 3), Fraction(1, 2), Fraction(1, 4)
    exact = [[Fraction(0)] * 6 for _ in range(6)]
    exact[0][1] = exact[0][2] = exact[0][3] = third
    exact[1][4], exact[1][0], exact[1][1] = half, quarter, quarter
    exact[2][3] = exact[2][5] = half
    exact[3][3] = exact[3][5] = half
    exact[4][4] = exact[5][5] = Fraction(1)
    P = sp.csr_matrix(np.array([[float(v) for v in row] for row in exact]))
    return P, exact


def test_until_on_a_shared_system_with_zero_states_encloses_the_exact_values() -> None:
    P, exact = _chain()
    target, sink = np.zeros(6, dtype=bool), np.zeros(6, dtype=bool)
    target[4], sink[5] = True, True
    workspace = Workspace()
    # states 0..3: the kept (shared) system
    kernels.prepare_reach(P, target | sink, workspace=workspace)
    found = kernels.until_probs(P, np.ones(6, dtype=bool), target, workspace=workspace)
    # x1 = 1/2 + x0/4 + x1/4 and x0 = x1/3: x1 = 1/2 + x1/12 + x1/4, so x1 = 3/4, x0 = 1/4.
    expected = [Fraction(1, 4), Fraction(3, 4), Fraction(0), Fraction(0), Fraction(1),
                Fraction(0)]
    for state in range(4):  # the hand solution is the fixed point, in exact arithmetic
        assert expected[state] == sum(p * v for p, v in zip(exact[state], expected, strict=True))
    for state, value in enumerate(expected):
        assert Fraction(found.lower[state]) <= value <= Fraction(found.upper[state])
        assert found.value[state] == float(value)
    assert found.upper[2] == found.upper[3] == 0.0  # no states: exact from the pre-pass
