"""SCC-by-SCC solving in topological order (checker/linalg/topological.py), certified.

The solver only proposes values; the existing certificate (checker/certify/) bounds them.
Each test asserts which method solved which states, the values against an
independent answer (a closed form, or Gauss-Jordan over Fractions in
tests/checker/exact_reference.py) and that the certified bounds contain it.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker import exact_reference as ref
from veribattery.checker import certify, linalg
from veribattery.checker.linalg import topological
from veribattery.errors import CheckError

GOAL_Q, GOAL_R, LOOP = 0.5, 0.25, 0.125  # next, goal, self-loop; the rest to a sink


def shuffled_chain(n: int, seed: int) -> tuple[sp.csr_matrix, np.ndarray, int, int]:
    """A chain of *n* states in random numbering: each moves on with GOAL_Q, to the
    goal with GOAL_R, stays with LOOP and falls into the sink otherwise (the last one
    falls with GOAL_Q too). Returns P, the numbering (``label[k]``: chain position
    k's state), the goal and the sink."""
    label = np.random.default_rng(seed).permutation(n)
    goal, sink = n, n + 1
    following = np.append(label[1:], sink)
    rows = np.concatenate([label, label, label, label, [goal, sink]])
    cols = np.concatenate([following, np.full(n, goal), label, np.full(n, sink), [goal, sink]])
    data = np.concatenate([np.full(n, GOAL_Q), np.full(n, GOAL_R), np.full(n, LOOP),
                           np.full(n, 1 - GOAL_Q - GOAL_R - LOOP), [1.0, 1.0]])
    P = sp.csr_matrix((data, (rows, cols)), shape=(n + 2, n + 2))
    return P, label, goal, sink


def certified(P: sp.csr_matrix, unknown: np.ndarray, goal: int,
              solver: topological.TopologicalSolver
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The solver's value of ``P(F goal)`` on *unknown* and the certificate's bounds."""
    known = np.zeros(P.shape[0])
    known[goal] = 1.0
    states = np.flatnonzero(unknown)
    rows = sp.csr_matrix(P[states])
    F = certify.AffineMap.of(rows, states, known, known, None)
    x = np.clip(solver(rows @ known), 0.0, 1.0)
    low, high = certify.certify_fixpoint(F, x, solver, np.zeros(states.size),
                                         np.ones(states.size))
    return x, low, high


def system(P: sp.csr_matrix, unknown: np.ndarray) -> sp.csr_matrix:
    """``I - P_mm`` as the checker builds it (leaving probabilities on the diagonal)."""
    A64, _, _ = linalg.restricted_parts(P, unknown)
    return A64


def test_million_state_chain_is_one_substitution() -> None:
    n = 1_000_000
    P, label, goal, _ = shuffled_chain(n, seed=1)
    unknown = np.zeros(n + 2, dtype=bool)
    unknown[:n] = True
    solver = topological.TopologicalSolver(system(P, unknown))
    assert solver.methods == {"substitution": n}
    assert len(solver.segments) == 1
    x, low, high = certified(P, unknown, goal, solver)
    # x_k = c + a x_{k+1} with a = q / (1 - s) = 4/7, c = r / (1 - s) = 2/7, from the
    # chain's end: x = (2/3) (1 - (4/7)^(n - k)) at chain position k.
    steps = n - np.arange(n)
    expected = (2.0 / 3.0) * -np.expm1(steps * np.log(4.0 / 7.0))
    np.testing.assert_allclose(x[label], expected, rtol=1e-13)
    assert np.all(low <= x) and np.all(x <= high)
    assert np.all(high - low <= 1e-12)
    # At the chain's end the exact values are short rationals: compare exactly.
    for k, exact in ((n - 1, Fraction(2, 7)), (n - 2, Fraction(2, 7) * (1 + Fraction(4, 7)))):
        state = label[k]
        assert Fraction(float(low[state])) <= exact <= Fraction(float(high[state]))


def components_in_series(seed: int) -> tuple[sp.csr_matrix, int]:
    """Upstream to downstream: a chain of 5 single states, three 3-cycles, a ring of
    12 states, two more single states, then the goal (and a sink). Every state leaves
    towards the next part with some probability, so each part is a component."""
    rng = np.random.default_rng(seed)
    parts = [[0], [1], [2], [3], [4], [5, 6, 7], [8, 9, 10], [11, 12, 13],
             list(range(14, 26)), [26], [27]]
    goal, sink = 28, 29
    entries: dict[tuple[int, int], float] = {}
    for index, part in enumerate(parts):
        after = parts[index + 1][0] if index + 1 < len(parts) else goal
        for position, state in enumerate(part):
            inside = part[(position + 1) % len(part)]
            weights = rng.integers(1, 8, size=4).astype(float)
            weights /= weights.sum()
            for target, weight in zip((inside, after, sink, goal), weights, strict=True):
                entries[state, target] = entries.get((state, target), 0.0) + float(weight)
    entries[goal, goal] = entries[sink, sink] = 1.0
    (rows, cols), data = zip(*entries.keys(), strict=True), list(entries.values())
    return sp.csr_matrix((data, (rows, cols)), shape=(30, 30)), goal


def test_components_in_series_take_each_method() -> None:
    P, goal = components_in_series(seed=3)
    unknown = np.zeros(30, dtype=bool)
    unknown[:28] = True
    asked: list[int] = []

    def ring_solver(block: sp.csr_matrix) -> topological.Inverse | None:
        asked.append(block.shape[0])
        return topological.direct_component(block)

    solver = topological.TopologicalSolver(system(P, unknown), ring_solver, small=4)
    assert solver.methods == {"substitution": 7, "blocks": 9, "component": 12}
    # Successors first: the two states before the goal, the ring, the 3-cycles, the chain.
    assert [s.method for s in solver.segments] == [
        "substitution", "component", "blocks", "substitution"]
    assert asked == [12]
    x, low, high = certified(P, unknown, goal, solver)
    target = np.zeros(30, dtype=bool)
    target[goal] = True
    exact = ref.until(P, np.ones(30, dtype=bool), target)
    exact_unknown = [exact[i] for i in range(28)]
    assert all(Fraction(float(lo)) <= v <= Fraction(float(hi))
               for lo, hi, v in zip(low, high, exact_unknown, strict=True))
    assert all(abs(Fraction(float(v)) - e) <= Fraction(1, 10**14) * e
               for v, e in zip(x, exact_unknown, strict=True))


def test_condensation_orders_successors_first() -> None:
    P, _ = components_in_series(seed=4)
    unknown = np.zeros(30, dtype=bool)
    unknown[:28] = True
    found = topological.condensation(system(P, unknown))
    assert found.count == 5 + 3 + 1 + 2
    position = np.empty(28, dtype=np.int64)
    position[found.order] = np.arange(28)
    # Downstream parts first: the last single state, then the ring, ..., state 0 last.
    assert position[27] == 0 and position[0] == 27
    assert sorted(np.diff(found.starts).tolist()) == [1] * 7 + [3, 3, 3, 12]


def test_progress_reports_each_segment() -> None:
    P, _ = components_in_series(seed=5)
    unknown = np.zeros(30, dtype=bool)
    unknown[:28] = True
    solver = topological.TopologicalSolver(system(P, unknown), small=4)
    told: list[tuple[int, int]] = []
    solver.solve(np.ones(28), progress=lambda done, total: told.append((done, total)))
    assert told == [(2, 28), (14, 28), (23, 28), (28, 28)]


def test_component_without_solver_is_an_error() -> None:
    P, _ = components_in_series(seed=6)
    unknown = np.zeros(30, dtype=bool)
    unknown[:28] = True
    with pytest.raises(CheckError, match="12 states"):
        topological.TopologicalSolver(system(P, unknown), lambda block: None, small=4)
