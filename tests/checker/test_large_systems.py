"""Systems above ``DIRECT_LIMIT`` unknowns: substitution or the SCC-by-SCC solve where the
structure allows it, the iterative fallback only for a component too large to factorise.

``DIRECT_LIMIT`` is lowered so that small models with exact answers stand for large ones.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker.chains import matrix
from veribattery.checker import Workspace, kernels
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.linalg import factorization

#: Chain lengths of the staged model (see :func:`_staged`).
SINGLES, PAIRS, WALK = 60, 20, 80


def _staged() -> tuple[sp.csr_matrix, int, int, Fraction]:
    """Singles with self-loops, then two-state cycles, then a symmetric walk; every state
    may fail. Returns ``(P, fail, goal, exact P(F goal) from state 0)``.

    * single ``j``: stay 0.3, next 0.6, fail 0.1 -- each passed with probability 6/7;
    * pair ``(a, b)``: ``a`` to ``b`` 0.5, next 0.4, fail 0.1; ``b`` back 0.9, fail 0.1 --
      ``v_a = 0.45 v_a + 0.4 v_next``, passed with probability 8/11;
    * walk over fortunes 0..WALK+1 (0 is fail, WALK+1 is goal), entered at fortune 40,
      step 1/2 either way: reaches the goal with probability 40 / (WALK + 1).
    """
    rows: dict[int, dict[int, float]] = {}
    pair0 = SINGLES
    walk0 = pair0 + 2 * PAIRS  # fortune k (1..WALK) is state walk0 + k - 1
    fail, goal = walk0 + WALK, walk0 + WALK + 1
    for j in range(SINGLES):
        rows[j] = {j: 0.3, j + 1: 0.6, fail: 0.1}
    for i in range(PAIRS):
        a, b = pair0 + 2 * i, pair0 + 2 * i + 1
        following = a + 2 if i + 1 < PAIRS else walk0 + 40 - 1
        rows[a] = {b: 0.5, following: 0.4, fail: 0.1}
        rows[b] = {a: 0.9, fail: 0.1}
    for k in range(1, WALK + 1):
        down = fail if k == 1 else walk0 + k - 2
        up = goal if k == WALK else walk0 + k
        rows[walk0 + k - 1] = {down: 0.5, up: 0.5}
    exact = Fraction(6, 7) ** SINGLES * Fraction(8, 11) ** PAIRS * Fraction(40, WALK + 1)
    return matrix(rows, goal + 1), fail, goal, exact


def _forward_chain(n: int) -> tuple[sp.csr_matrix, int, Fraction]:
    """Acyclic apart from self-loops: stay 0.25, next 0.7, fail 0.05; ``(P, goal, exact)``."""
    fail, goal = n, n + 1
    rows = {j: {j: 0.25, (j + 1 if j + 1 < n else goal): 0.7, fail: 0.05} for j in range(n)}
    return matrix(rows, n + 2), goal, Fraction(14, 15) ** n


def _solved(P: sp.csr_matrix, goal: int) -> tuple[Bounds, str | None]:
    """``P(F goal)`` from every state, and the method of the system's direct solver."""
    n = P.shape[0]
    target = np.zeros(n, dtype=bool)
    target[goal] = True
    workspace = Workspace()
    bounds = kernels.until_probs(P, np.ones(n, dtype=bool), target, workspace=workspace)
    (system,) = workspace.kernels.of(P).systems.values()
    return bounds, system.factorization.method


def _contains(bounds: Bounds, state: int, exact: Fraction) -> bool:
    return Fraction(float(bounds.lower[state])) <= exact <= Fraction(float(bounds.upper[state]))


def test_acyclic_chain_above_the_limit_is_solved_by_substitution(
        monkeypatch: pytest.MonkeyPatch) -> None:
    P, goal, exact = _forward_chain(500)
    monkeypatch.setattr(factorization, "DIRECT_LIMIT", 100)
    bounds, method = _solved(P, goal)
    assert method == "substitution"
    assert _contains(bounds, 0, exact)
    assert bounds.value[0] == pytest.approx(float(exact), rel=1e-12)


def test_components_above_the_limit_are_solved_in_topological_order(
        monkeypatch: pytest.MonkeyPatch) -> None:
    P, _, goal, exact = _staged()
    below, below_method = _solved(P, goal)
    assert below_method == "segmented"
    monkeypatch.setattr(factorization, "DIRECT_LIMIT", 100)  # 180 unknowns; walk of 80
    above, above_method = _solved(P, goal)
    assert above_method == "topological"
    for bounds in (below, above):
        assert _contains(bounds, 0, exact)
        assert bounds.value[0] == pytest.approx(float(exact), rel=1e-12)


def test_a_component_too_large_to_factorise_falls_back_to_the_iterative_solver(
        monkeypatch: pytest.MonkeyPatch) -> None:
    P, _, goal, exact = _staged()
    monkeypatch.setattr(factorization, "DIRECT_LIMIT", 70)  # the walk (80) is larger
    bounds, method = _solved(P, goal)
    assert method is None
    assert _contains(bounds, 0, exact)
