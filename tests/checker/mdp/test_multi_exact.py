"""The exact witness of an achievability query: a vertex re-solved in rationals."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from veribattery.checker.mdp.multi_exact import exact_witness

# x0 + x1 = 1 over x >= 0 (one flow row).
FLOW = sp.csr_matrix(np.array([[1.0, 1.0]]))
START = np.array([1.0])


def test_a_vertex_on_the_boundary_is_proved() -> None:
    # x0 >= 0.1 + 0.2 (a sum that is not 0.3 in doubles) at x0 = 0.30000000000000004:
    # the tight row fixes x0 to the bound's exact rational, which meets it.
    bound = -(0.1 + 0.2)
    point = np.array([0.1 + 0.2, 1 - (0.1 + 0.2)])
    assert exact_witness(FLOW, START, np.array([[-1.0, 0.0]]), np.array([bound]), point, 1e-6)


def test_a_bound_missed_in_exact_arithmetic_is_not_proved() -> None:
    # x0 >= 0.5 and x1 >= 0.5 + 1e-12: floating point within tolerance, exactly infeasible
    rows = np.array([[-1.0, 0.0], [0.0, -1.0]])
    bounds = np.array([-0.5, -(0.5 + 1e-12)])
    assert not exact_witness(FLOW, START, rows, bounds, np.array([0.5, 0.5]), 1e-6)


def test_a_negative_exact_solution_is_not_proved() -> None:
    # x0 <= -1e-12 is tight (within tolerance) at x0 = 1e-8: solved exactly, x0 < 0
    rows = np.array([[1.0, 0.0]])
    point = np.array([1e-8, 1.0 - 1e-8])
    assert not exact_witness(FLOW, START, rows, np.array([-1e-12]), point, 1e-6)


def test_a_satisfied_bound_with_slack_is_proved() -> None:
    rows = np.array([[-1.0, 0.0]])  # x0 >= 0.25 at the vertex x0 = 1
    assert exact_witness(FLOW, START, rows, np.array([-0.25]), np.array([1.0, 0.0]), 1e-6)
