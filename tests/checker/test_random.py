"""Property-based: kernels against dense numpy computations on random small DTMCs.

The reference computes the qualitative sets by a dense boolean fixpoint and the
values with ``numpy.linalg.solve`` on the states that can reach the target (no
prob1 pre-pass), so it shares no code with the kernels.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from veribattery.checker import Workspace, kernels


@st.composite
def chains(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A dense stochastic matrix with 1-3 successors per state, masks and rewards."""
    n = draw(st.integers(2, 10))
    dense = np.zeros((n, n))
    for s in range(n):
        successors = draw(st.lists(st.integers(0, n - 1), min_size=1, max_size=3, unique=True))
        weights = draw(st.lists(st.integers(1, 9), min_size=len(successors),
                                max_size=len(successors)))
        dense[s, successors] = np.asarray(weights) / sum(weights)
    flags = st.lists(st.booleans(), min_size=n, max_size=n)
    remain, target = np.array(draw(flags)), np.array(draw(flags))
    rewards = np.array(draw(st.lists(st.integers(0, 5), min_size=n, max_size=n)), dtype=float)
    return dense, remain, target, rewards


def _can_reach(dense: np.ndarray, through: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """Dense fixpoint: seeds, or states in *through* with an edge into the set."""
    reached = seeds.copy()
    for _ in range(len(seeds)):
        reached = seeds | (through & ((dense > 0) @ reached))
    return reached


def _dense_until(dense: np.ndarray, remain: np.ndarray, target: np.ndarray) -> np.ndarray:
    positive = _can_reach(dense, remain & ~target, target)
    solve = positive & ~target
    result = target.astype(float)
    inner = dense[np.ix_(solve, solve)]
    rhs = dense[np.ix_(solve, target)].sum(axis=1)
    result[solve] = np.linalg.solve(np.eye(int(solve.sum())) - inner, rhs)
    return result


def _dense_reach_rewards(dense: np.ndarray, rewards: np.ndarray, target: np.ndarray) -> np.ndarray:
    everywhere = np.ones(len(target), dtype=bool)
    stuck = ~_can_reach(dense, everywhere, target)
    unsure = _can_reach(dense, ~target, stuck)
    result = np.where(unsure, np.inf, 0.0)
    solve = ~unsure & ~target
    inner = dense[np.ix_(solve, solve)]
    result[solve] = np.linalg.solve(np.eye(int(solve.sum())) - inner, rewards[solve])
    return result


@settings(max_examples=300, deadline=None)
@given(chains())
def test_until_matches_dense_solve(case: tuple[np.ndarray, ...]) -> None:
    dense, remain, target, _ = case
    result = kernels.until_probs(sp.csr_matrix(dense), remain, target, workspace=Workspace()).value
    assert result.tolist() == pytest.approx(_dense_until(dense, remain, target).tolist(),
                                            rel=1e-9, abs=1e-12)


@settings(max_examples=300, deadline=None)
@given(chains())
def test_reach_rewards_match_dense_solve(case: tuple[np.ndarray, ...]) -> None:
    dense, _, target, rewards = case
    result = kernels.reach_rewards(sp.csr_matrix(dense), rewards, target,
                                   workspace=Workspace()).value
    expected = _dense_reach_rewards(dense, rewards, target)
    assert np.array_equal(np.isinf(result), np.isinf(expected))
    finite = np.isfinite(expected)
    assert result[finite].tolist() == pytest.approx(expected[finite].tolist(), rel=1e-9,
                                                    abs=1e-12)


@settings(max_examples=200, deadline=None)
@given(chains(), st.integers(0, 12))
def test_step_bounded_kernels_match_dense_iteration(case: tuple[np.ndarray, ...], k: int) -> None:
    dense, remain, target, rewards = case
    P = sp.csr_matrix(dense)
    bounded, cumulative, instant = target.astype(float), np.zeros(len(target)), rewards
    for _ in range(k):
        bounded = np.where(target, 1.0, np.where(remain, dense @ bounded, 0.0))
        cumulative = rewards + dense @ cumulative
        instant = dense @ instant
    assert kernels.bounded_until_probs(P, remain, target, k).value.tolist() == pytest.approx(
        bounded.tolist(), rel=1e-12, abs=1e-15)
    assert kernels.cumulative_rewards(P, rewards, k).value.tolist() == pytest.approx(
        cumulative.tolist(), rel=1e-12)
    assert kernels.instantaneous_rewards(P, rewards, k).value.tolist() == pytest.approx(
        instant.tolist(), rel=1e-12)


@settings(max_examples=200, deadline=None)
@given(chains(), st.integers(0, 6))
def test_lower_bounded_until_matches_dense_iteration(case: tuple[np.ndarray, ...],
                                                     k: int) -> None:
    dense, remain, target, _ = case
    later = _dense_until(dense, remain, target)
    for _ in range(k):
        later = np.where(remain, dense @ later, 0.0)
    result = kernels.lower_bounded_until_probs(sp.csr_matrix(dense), remain, target, k,
                                               workspace=Workspace()).value
    assert result.tolist() == pytest.approx(later.tolist(), rel=1e-9, abs=1e-12)
