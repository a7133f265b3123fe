"""Certified ``F{"r"}<=T``: the forward-error radius (checker/kernels/reward_radius.py)
against exact rationals, the escalation to per-level certification when the radius is too
wide, a stiff closure, exact zeros, and the least-reward search against a brute-force one."""

from __future__ import annotations

import random
from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker import exact_reference as ref
from tests.checker.chains import matrix
from veribattery.checker import Workspace, kernels
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.kernels import reward_radius
from veribattery.checker.kernels.reward_bounded import _levels, reward_bounded_until_bounds

Rows = dict[int, dict[int, float]]


# ---------------------------------------------------------------------------
# An exact oracle: the level programme in rationals, closures by Gaussian elimination
# ---------------------------------------------------------------------------


def _exact(rows: Rows, rewards: list[int], target: set[int], bound: int) -> list[Fraction]:
    """P(F{r}<=bound target) per state for the model as built: the stored float entries
    as rationals; on zero-reward states the self-loop read as 1 - (sum of the others)."""
    n = len(rewards)
    P = {s: {t: Fraction(p) for t, p in rows.get(s, {s: 1.0}).items()} for s in range(n)}
    # States that can reach the target at all (others are 0).
    alive = set(target)
    while True:
        more = {s for s in range(n) if s not in alive and any(t in alive for t in P[s])}
        if not more:
            break
        alive |= more
    moving = [s for s in range(n) if s in alive and s not in target]
    zero = [s for s in moving if rewards[s] == 0]
    history: list[list[Fraction]] = []
    for k in range(bound + 1):
        v = [Fraction(1) if s in target else Fraction(0) for s in range(n)]
        for s in moving:
            if rewards[s] > 0 and k >= rewards[s]:
                before = history[k - rewards[s]]
                v[s] = sum((p * before[t] for t, p in P[s].items()), Fraction(0))
        if zero:
            where = {s: i for i, s in enumerate(zero)}
            A = [[Fraction(0)] * len(zero) for _ in zero]
            b = [Fraction(0)] * len(zero)
            for s in zero:
                i = where[s]
                A[i][i] = sum((p for t, p in P[s].items() if t != s), Fraction(0))
                for t, p in P[s].items():
                    if t == s:
                        continue
                    if t in where:
                        A[i][where[t]] -= p
                    else:
                        b[i] += p * v[t]
            for s, value in zip(zero, ref.solve(A, b), strict=True):
                v[s] = value
        history.append(v)
    return history[-1]


def _contains(found: Bounds, exact: list[Fraction]) -> bool:
    return all(Fraction(float(lo)) <= x <= Fraction(float(hi))
               for lo, hi, x in zip(found.lower, found.upper, exact, strict=True))


def _random_chain(seed: int, n: int = 9) -> tuple[Rows, list[int], set[int]]:
    """Random rows (floats that need not sum to 1 exactly), rewards 0..3 with some zero-reward
    cycles, two targets and one sink."""
    rng = random.Random(seed)
    target, sink = {n - 2}, n - 1
    rows: Rows = {}
    for s in range(n - 2):
        succ = rng.sample(range(n), rng.randint(1, 4))
        weights = [rng.random() + 0.05 for _ in succ]
        total = sum(weights)
        rows[s] = {t: w / total for t, w in zip(succ, weights, strict=True)}
    rows[sink] = {sink: 1.0}
    rewards = [rng.choice([0, 0, 1, 2, 3]) for _ in range(n - 2)] + [0, 0]
    return rows, rewards, target


def _kernel(rows: Rows, rewards: list[int], target: set[int], bound: int) -> Bounds:
    n = len(rewards)
    P = matrix(rows, n)
    goal = np.isin(np.arange(n), list(target))
    return reward_bounded_until_bounds(P, np.ones(n, dtype=bool), goal,
                                       np.array(rewards, dtype=np.int64), bound,
                                       workspace=Workspace())


def _radius_only(rows: Rows, rewards: list[int], target: set[int], bound: int) -> Bounds | None:
    """The fast path alone, without the escalation."""
    n = len(rewards)
    P = matrix(rows, n)
    goal = np.isin(np.arange(n), list(target))
    everywhere = np.ones(n, dtype=bool)
    moving = everywhere & ~goal & ~kernels.prob0(P, everywhere, goal, workspace=Workspace())
    r = np.array(rewards, dtype=np.int64)
    levels = _levels(P, moving, r, transpose=False)
    return reward_radius.radius_programme(P, moving, goal, r, levels, bound // levels.unit)


# ---------------------------------------------------------------------------
# The radius alone contains the exact value and meets the precision
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(16))
def test_random_chains_radius_contains_exact_and_is_precise(seed: int) -> None:
    rows, rewards, target = _random_chain(seed)
    for bound in (0, 1, 4, 9):
        exact = _exact(rows, rewards, target, bound)
        fast = _radius_only(rows, rewards, target, bound)
        assert fast is not None
        assert _contains(fast, exact), (seed, bound)
        assert fast.precise_states().all(), (seed, bound, fast.width.max())
        found = _kernel(rows, rewards, target, bound)
        assert _contains(found, exact) and found.precise_states().all()
        assert np.all(found.lower <= found.value) and np.all(found.value <= found.upper)


def test_zero_reward_loop_closed_form() -> None:
    # s0 (reward 0) stays w.p. 1/2 or moves to s1 (reward 1), which wins w.p. 1/3 or
    # returns: P(F{r}<=k goal) = 1 - (2/3)^k from s0 and s1.
    rows: Rows = {0: {0: 0.5, 1: 0.5}, 1: {2: 1 / 3, 0: 2 / 3}}
    for k in (1, 2, 30):
        found = _kernel(rows, [0, 1, 0], {2}, k)
        exact = _exact(rows, [0, 1, 0], {2}, k)
        # The stored 1/3 and 2/3 are floats: the exact value of the model as built is
        # within 1e-15 of 1 - (2/3)^k, and the interval contains it.
        assert abs(float(exact[0]) - (1 - (2 / 3) ** k)) < 1e-14
        assert _contains(found, exact) and found.precise_states().all()


def test_states_out_of_budget_are_exactly_zero() -> None:
    # 0 -> 1 -> 2 (goal), rewards 2 and 3: from 0 nothing reaches the goal below 5, so
    # its interval is [0, 0] (no rounding noise); from 1 it costs 3; at 5, 0 has 3/4.
    rows: Rows = {0: {1: 0.75, 3: 0.25}, 1: {2: 1.0}}
    low = _kernel(rows, [2, 3, 0, 0], {2}, 4)
    assert (low.lower[0], low.upper[0], low.lower[3], low.upper[3]) == (0.0, 0.0, 0.0, 0.0)
    assert low.lower[1] <= 1.0 == low.upper[1] and low.precise_states().all()
    high = _kernel(rows, [2, 3, 0, 0], {2}, 5)
    assert high.value[0] == 0.75 and high.lower[0] <= 0.75 <= high.upper[0]


# ---------------------------------------------------------------------------
# Escalation: the radius too wide, per-level certification precise
# ---------------------------------------------------------------------------


def _ring_with_hub(p: float, spokes: int) -> tuple[Rows, list[int], set[int]]:
    """A ring of 4 reward-1 states, each winning w.p. *p* or moving on, and a reward-1 hub
    with *spokes* equally likely target states: the hub's many terms make the group's
    rounding coefficient (its largest row's) ~spokes times the ring rows' own."""
    ring = 4
    hub = ring
    first = ring + 1
    rows: Rows = {s: {(s + 1) % ring: 1 - p, first: p} for s in range(ring)}
    rows[hub] = {first + i: 1.0 / spokes for i in range(spokes)}
    rewards = [1] * (ring + 1) + [0] * spokes
    return rows, rewards, set(range(first, first + spokes))


def test_radius_too_wide_escalates_to_certified_levels() -> None:
    p, spokes, bound = 2.0**-10, 4096, 3000
    rows, rewards, target = _ring_with_hub(p, spokes)
    fast = _radius_only(rows, rewards, target, bound)
    assert fast is not None and not fast.precise_states()[0]  # the cheap radius: too wide
    found = _kernel(rows, rewards, target, bound)
    exact = 1 - (1 - Fraction(p)) ** bound  # every ring state, by symmetry
    for s in range(4):
        assert Fraction(float(found.lower[s])) <= exact <= Fraction(float(found.upper[s]))
    assert found.precise_states().all()
    # The result is the intersection of two certified intervals.
    assert np.all(found.lower >= fast.lower) and np.all(found.upper <= fast.upper)


def test_stiff_closure_stays_certified() -> None:
    # Two zero-reward states bounce between each other and leave w.p. 1e-9 each time:
    # the closure's condition number (and tau) is ~1e9. Whatever path answers, the
    # interval contains the exact value, and "precise" is true only if the width says so.
    eps = 1e-9
    rows: Rows = {0: {1: 1 - eps, 2: eps}, 1: {0: 1 - eps, 3: eps}, 2: {4: 0.5, 5: 0.5},
                  3: {4: 0.25, 5: 0.75}}
    rewards = [0, 0, 1, 2, 0, 0]
    for bound in (1, 2, 6):
        exact = _exact(rows, rewards, {4}, bound)
        found = _kernel(rows, rewards, {4}, bound)
        assert _contains(found, exact), bound
        allowed = np.maximum(1e-9 * np.abs(found.value), 1e-12)
        assert np.array_equal(found.precise_states(), found.width <= allowed)


# ---------------------------------------------------------------------------
# The least reward to the target (exact zeros)
# ---------------------------------------------------------------------------


def _least_brute_force(P: sp.csr_matrix, moving: np.ndarray, target: np.ndarray,
                       rewards: np.ndarray) -> list[float]:
    n = P.shape[0]
    best = [0.0 if target[s] else float("inf") for s in range(n)]
    for _ in range(n):  # Bellman-Ford
        for s in range(n):
            if moving[s]:
                row = P.indices[P.indptr[s]:P.indptr[s + 1]]
                best[s] = min([best[s]] + [rewards[s] + best[t] for t in row])
    return best


@pytest.mark.parametrize("seed", range(10))
def test_minimal_rewards_against_bellman_ford(seed: int) -> None:
    rows, rewards, target = _random_chain(seed, n=12)
    n = len(rewards)
    P = matrix(rows, n)
    goal = np.isin(np.arange(n), list(target))
    moving = ~goal & ~kernels.prob0(P, np.ones(n, dtype=bool), goal, workspace=Workspace())
    r = np.array(rewards, dtype=np.int64)
    found = reward_radius._minimal_rewards(P, moving, goal, r)
    assert found.tolist() == _least_brute_force(P, moving, goal, r)
