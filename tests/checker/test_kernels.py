"""Kernels against closed forms and hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker.chains import gamblers_ruin, knuth_die, mask, matrix
from veribattery.checker import Workspace, kernels, linalg
from veribattery.checker.linalg import factorization, iterative, triangular
from veribattery.errors import CheckError

ALL13 = np.ones(13, dtype=bool)


def _ruin_win(i: int, n: int, p: float) -> float:
    if p == 0.5:
        return i / n
    r = (1 - p) / p
    return (r**i - 1) / (r**n - 1)


def _ruin_duration(i: int, n: int, p: float) -> float:
    if p == 0.5:
        return float(i * (n - i))
    q = 1 - p
    r = q / p
    return i / (q - p) - n / (q - p) * (1 - r**i) / (1 - r**n)


# --- qualitative pre-pass -------------------------------------------------------


def test_prob0_prob1_on_die() -> None:
    die = knuth_die()
    P, target = die.transitions, die.labels["face1"]
    workspace = Workspace()
    no = kernels.prob0(P, ALL13, target, workspace=workspace)
    yes = kernels.prob1(P, ALL13, target, no, workspace=workspace)
    assert np.flatnonzero(~no).tolist() == [0, 1, 3, 7]
    assert np.flatnonzero(yes).tolist() == [7]


def test_prob0_respects_remain() -> None:
    # 0 -> 1 -> 2 (target); leaving 1 out of remain cuts 0 off.
    P = matrix({0: {1: 1.0}, 1: {2: 1.0}}, 3)
    no = kernels.prob0(P, mask(3, [0]), mask(3, [2]), workspace=Workspace())
    assert no.tolist() == [True, True, False]


def test_prob0_ignores_explicit_zero_entries() -> None:
    P = matrix({0: {1: 0.0, 0: 1.0}}, 2)
    assert kernels.prob0(P, mask(2, [0, 1]), mask(2, [1]),
                         workspace=Workspace()).tolist() == [True, False]


def test_prob0_on_long_chain_is_fast() -> None:
    # 200k-state chain: a mat-vec fixpoint would need 200k iterations.
    n = 200_000
    P = matrix({i: {i + 1: 1.0} for i in range(n - 1)}, n)
    no = kernels.prob0(P, np.ones(n, dtype=bool), mask(n, [n - 1]), workspace=Workspace())
    assert not no.any()


# --- unbounded until ---------------------------------------------------------------


@pytest.mark.parametrize("face", range(1, 7))
def test_die_faces_are_one_sixth(face: int) -> None:
    die = knuth_die()
    probs = kernels.until_probs(die.transitions, ALL13, die.labels[f"face{face}"],
                                workspace=Workspace()).value
    assert probs[0] == pytest.approx(1 / 6, rel=1e-12)


def test_die_expected_flips() -> None:
    die = knuth_die()
    flips = kernels.reach_rewards(die.transitions, die.rewards[0].total, die.labels["done"],
                                  workspace=Workspace()).value
    assert flips[0] == pytest.approx(11 / 3, rel=1e-12)
    assert flips[7:].tolist() == [0.0] * 6


@pytest.mark.parametrize(("n", "p"), [(10, 0.5), (20, 0.4), (20, 0.6), (50, 0.3), (100, 0.49)],
                         ids=str)
def test_gamblers_ruin_closed_forms(n: int, p: float) -> None:
    chain = gamblers_ruin(n, p)
    P = chain.transitions
    workspace = Workspace()
    win = kernels.until_probs(P, np.ones(n + 1, dtype=bool), chain.labels["win"],
                              workspace=workspace).value
    steps = kernels.reach_rewards(P, chain.rewards[0].total, chain.labels["end"],
                                  workspace=workspace).value
    for i in range(n + 1):
        assert win[i] == pytest.approx(_ruin_win(i, n, p), rel=1e-9)
        assert steps[i] == pytest.approx(_ruin_duration(i, n, p), rel=1e-9, abs=1e-9)


def test_until_with_remain_restriction() -> None:
    # 0 -> {1: .5, 2: .5}, 1 -> 3 (target), 2 -> 3; only 1 may be passed through.
    P = matrix({0: {1: 0.5, 2: 0.5}, 1: {3: 1.0}, 2: {3: 1.0}}, 4)
    probs = kernels.until_probs(P, mask(4, [0, 1]), mask(4, [3]), workspace=Workspace()).value
    assert probs.tolist() == pytest.approx([0.5, 1.0, 0.0, 1.0])


def test_until_with_near_one_self_loop() -> None:
    # Leaving probability 1e-12: 1 - P_ii would lose four digits; the off-diagonal sum does not.
    eps = 1e-12
    P = matrix({0: {0: 1 - eps, 1: eps / 4, 2: 3 * eps / 4}}, 3)
    probs = kernels.until_probs(P, np.ones(3, dtype=bool), mask(3, [1]),
                                workspace=Workspace()).value
    assert probs[0] == pytest.approx(0.25, rel=1e-12)


# --- rewards -------------------------------------------------------------------------


def test_reach_reward_is_infinite_without_almost_sure_reach() -> None:
    # 0 -> 1 (target) or 2 (trap); reward 0 in the trap still gives inf (PRISM).
    P = matrix({0: {1: 0.5, 2: 0.5}}, 3)
    result = kernels.reach_rewards(P, np.array([1.0, 5.0, 0.0]), mask(3, [1]),
                                   workspace=Workspace()).value
    assert result.tolist() == [np.inf, 0.0, np.inf]


def test_reach_reward_zero_rewards() -> None:
    P = matrix({0: {0: 0.5, 1: 0.5}}, 2)
    assert kernels.reach_rewards(P, np.zeros(2), mask(2, [1]),
                                 workspace=Workspace()).value.tolist() == [0.0, 0.0]


# 0 stays with 1/2 or moves to the absorbing 1; state reward 1 and transition reward 2 in 0,
# state reward 10 in 1.
GEOMETRIC = matrix({0: {0: 0.5, 1: 0.5}}, 2)


@pytest.mark.parametrize("k", [0, 1, 2, 5, 30])
def test_cumulative_rewards(k: int) -> None:
    total = np.array([3.0, 10.0])
    result = kernels.cumulative_rewards(GEOMETRIC, total, k).value
    expected0 = sum(3 * 0.5**i + 10 * (1 - 0.5**i) for i in range(k))
    assert result.tolist() == pytest.approx([expected0, 10.0 * k], rel=1e-12)


@pytest.mark.parametrize("k", [0, 1, 2, 5, 60])
def test_instantaneous_rewards(k: int) -> None:
    result = kernels.instantaneous_rewards(GEOMETRIC, np.array([1.0, 10.0]), k).value
    assert result.tolist() == pytest.approx([0.5**k + 10 * (1 - 0.5**k), 10.0], rel=1e-12)


# --- step-bounded probabilities -----------------------------------------------------

# 0: stay 1/2, to 1 1/2; 1: to target 2 1/2, back to 0 1/2; 2 absorbs.
LADDER = matrix({0: {0: 0.5, 1: 0.5}, 1: {2: 0.5, 0: 0.5}}, 3)
LADDER_F = {0: [0, 0, 1], 1: [0, 0.5, 1], 2: [0.25, 0.5, 1], 3: [0.375, 0.625, 1]}


@pytest.mark.parametrize("k", sorted(LADDER_F))
def test_bounded_until_hand_values(k: int) -> None:
    result = kernels.bounded_until_probs(LADDER, np.ones(3, dtype=bool), mask(3, [2]), k).value
    assert result.tolist() == pytest.approx(LADDER_F[k], rel=1e-12)


def test_bounded_until_respects_remain() -> None:
    result = kernels.bounded_until_probs(LADDER, mask(3, [1]), mask(3, [2]), 3).value
    assert result.tolist() == pytest.approx([0.0, 0.5, 1.0])


def test_bounded_until_large_k_stops_at_fixpoint() -> None:
    P = matrix({0: {1: 1.0}}, 2)
    found = kernels.bounded_until_probs(P, mask(2, [0, 1]), mask(2, [1]), 10**9)
    assert found.value.tolist() == [1, 1]


# 0 -> 1 -> 2 -> 2; target {1} is visited exactly at step 1 from 0.
PATH = matrix({0: {1: 1.0}, 1: {2: 1.0}}, 3)


@pytest.mark.parametrize(("k", "expected"), [(0, [1, 1, 0]), (1, [1, 0, 0]), (2, [0, 0, 0])])
def test_lower_bounded_until(k: int, expected: list[float]) -> None:
    result = kernels.lower_bounded_until_probs(PATH, np.ones(3, dtype=bool), mask(3, [1]), k,
                                               workspace=Workspace()).value
    assert result.tolist() == expected


def test_lower_bounded_until_needs_remain_before_k() -> None:
    # On LADDER, F>=1 target from 0 is 1, but with remain = {1, 2} state 0 fails at once.
    result = kernels.lower_bounded_until_probs(LADDER, mask(3, [1, 2]), mask(3, [2]), 1,
                                               workspace=Workspace()).value
    assert result.tolist() == pytest.approx([0.0, 0.5, 1.0])


def test_next_probs() -> None:
    assert kernels.next_probs(LADDER, mask(3, [1, 2])).value.tolist() == [0.5, 0.5, 1.0]


# --- solver fallback -----------------------------------------------------------------


def _ruin_system(n: int, p: float) -> tuple[sp.csr_matrix, np.ndarray]:
    chain = gamblers_ruin(n, p)
    A, rows = linalg.restricted_matrix(chain.transitions, ~chain.labels["end"])
    return A, rows.astype(np.longdouble) @ chain.labels["win"].astype(np.longdouble)


def test_iterative_fallback_meets_residual_rule() -> None:
    A, b = _ruin_system(30, 0.45)
    x = iterative.solve_iterative(sp.csr_matrix(A.astype(float)), b.astype(float), None)
    assert linalg.backward_error(A, x, b) <= iterative.RESIDUAL_TOL
    expected = [_ruin_win(i, 30, 0.45) for i in range(1, 30)]
    assert x.tolist() == pytest.approx(expected, rel=1e-8)


def test_direct_limit_zero_still_solves_small_cycles(monkeypatch: pytest.MonkeyPatch) -> None:
    # Above the limit the die's small cycles are solved SCC by SCC (test_large_systems).
    monkeypatch.setattr(factorization, "DIRECT_LIMIT", 0)
    die = knuth_die()
    probs = kernels.until_probs(die.transitions, ALL13, die.labels["face3"],
                                workspace=Workspace()).value
    assert probs[0] == pytest.approx(1 / 6, rel=1e-10)


def test_unsolvable_system_raises(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(factorization, "DIRECT_LIMIT", 0)
    monkeypatch.setattr(iterative, "ITERATIVE_MAXITER", 1)
    A, b = _ruin_system(200, 0.5)
    with pytest.raises(CheckError, match="backward error"):
        linalg.solve(A, b)


def test_refinement_recovers_accuracy_on_a_long_symmetric_walk() -> None:
    # cond ~ n^2 = 1e10: plain LU loses ~5 digits here; refined, it keeps ~15.
    n = 100_000
    A, b = _ruin_system(n, 0.5)
    x = linalg.solve(A, b)
    exact = np.arange(1, n) / n
    assert np.max(np.abs(x - exact) / exact) < 1e-12


# --- acyclic systems, shared systems -------------------------------------------------


def test_acyclic_system_is_solved_by_substitution() -> None:
    # A forward-only chain with self-loops: triangular in a topological order.
    n = 50
    rng = np.random.default_rng(1)
    P = matrix({i: {i: 0.3, i + 1: 0.5, min(i + 2, n - 1): 0.2} for i in range(n - 1)}, n)
    A, _rows = linalg.restricted_matrix(P, mask(n, range(n - 1)))
    A64 = sp.csr_matrix(A.astype(np.float64))
    inverse = triangular._triangular_inverse(A64)
    assert inverse is not None
    b = rng.random(n - 1)
    assert np.allclose(A64 @ inverse(b), b, rtol=1e-13)
    x = linalg.solve(A, b.astype(np.longdouble))
    assert np.allclose(x, sp.linalg.spsolve(A64.tocsc(), b), rtol=1e-12)


def test_cyclic_system_is_not_triangular() -> None:
    A, _b = _ruin_system(10, 0.5)
    assert triangular._triangular_inverse(sp.csr_matrix(A.astype(np.float64))) is None


def test_superlu_triangular_entry_point_is_used() -> None:
    lower = sp.csc_matrix(np.array([[1.0, 0.0], [-0.5, 1.0]]))
    substitute = triangular._substitution(lower)
    assert substitute.__name__ == "private"  # scipy's private API still behaves
    assert substitute(np.array([1.0, 0.0])).tolist() == [1.0, 0.5]


def test_reward_properties_on_one_target_share_their_system() -> None:
    chain = gamblers_ruin(20, 0.4)
    P, end = chain.transitions, chain.labels["end"]
    workspace = Workspace()
    steps = kernels.reach_rewards(P, np.ones(P.shape[0]), end, workspace=workspace).value
    doubled = kernels.reach_rewards(P, np.full(P.shape[0], 2.0), end, workspace=workspace).value
    assert len(workspace.kernels.of(P).systems) == 1
    np.testing.assert_allclose(doubled, 2 * steps, rtol=1e-13)
    expected = [_ruin_duration(i, 20, 0.4) for i in range(1, 20)]
    assert steps[1:20].tolist() == pytest.approx(expected, rel=1e-10)
