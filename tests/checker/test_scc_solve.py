"""SCC-wise solving for any component size (checker/linalg/scc.py), certified.

The size thresholds are lowered with monkeypatch so that small models (whose
exact answers are computed independently in Fraction arithmetic) take the
large-component paths: sparse LU with a fill-reducing order, and the
multigrid-preconditioned Krylov method.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker import exact_reference as ref
from tests.checker.chains import matrix
from veribattery.checker import Workspace, kernels, linalg
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.linalg import scc


def contains(found: Bounds, exact: list[Fraction]) -> bool:
    """Every exact value inside its state's certified interval (compared exactly)."""
    return all(Fraction(float(lo)) <= v <= Fraction(float(hi))
               for lo, hi, v in zip(found.lower, found.upper, exact, strict=True))


def ring_then_walk(ring: int, walk: int, seed: int) -> sp.csr_matrix:
    """A ring of *ring* states feeding a random walk of *walk* states, then a goal.

    Both are single SCCs (the ring is left with small probability at each state;
    the walk moves both ways and leaves from its right end), joined in series,
    with a few trivial states in between: three segments of every kind.
    """
    rng = np.random.default_rng(seed)
    n = ring + 3 + walk + 1
    goal = n - 1
    rows: dict[int, dict[int, float]] = {}
    for s in range(ring):
        leave = int(rng.integers(1, 4)) / 8  # dyadic: small exact references
        rows[s] = {(s + 1) % ring: 1 - leave, ring: leave}
    rows[ring] = {ring + 1: 0.5, ring + 2: 0.5}
    rows[ring + 1] = {ring + 2: 0.75, ring + 1: 0.25}
    rows[ring + 2] = {ring + 3: 1.0}
    first = ring + 3
    for k in range(walk):
        s = first + k
        up = int(rng.integers(1, 4)) / 4
        rows[s] = {s + 1 if k < walk - 1 else goal: up, max(s - 1, first): 1 - up}
    return matrix(rows, n)


@pytest.fixture
def small_limits(monkeypatch: pytest.MonkeyPatch) -> None:
    """Components above 4 states are 'large'; above 14 they go to the Krylov method."""
    monkeypatch.setattr(scc, "BLOCK_LIMIT", 4)
    monkeypatch.setattr(scc, "LU_LIMIT", 14)
    monkeypatch.setattr(scc, "ENVELOPE_LIMIT", 0)  # the 20-state walk is thin: no LU


def test_segments_isolate_large_components(small_limits: None) -> None:
    P = ring_then_walk(10, 20, seed=0)
    maybe = np.ones(P.shape[0], dtype=bool)
    maybe[-1] = False
    A64, _, _ = linalg.restricted_parts(P, maybe)
    found = scc.components(A64)
    assert found is not None
    assert found.largest == 20
    parts = scc.segments(found)
    large = [(hi - lo) for lo, hi, alone in parts if alone]
    assert sorted(large) == [10, 20]
    assert sum(hi - lo for lo, hi, _ in parts) == A64.shape[0]
    # The walk (successor of everything) comes first: successors precede.
    assert parts[0][2] and parts[0][1] - parts[0][0] == 20


@pytest.mark.parametrize("seed", range(3))
def test_large_components_against_fractions(small_limits: None, seed: int) -> None:
    P = ring_then_walk(10, 20, seed=seed)
    n = P.shape[0]
    target = np.zeros(n, dtype=bool)
    target[-1] = True
    everywhere = np.ones(n, dtype=bool)
    rewards = (np.arange(n) % 4 + 1) / 2
    workspace = Workspace()
    found = kernels.reach_rewards(P, rewards, target, workspace=workspace)
    assert contains(found, ref.reach_rewards(P, rewards, target))
    assert found.precise_states().all()
    # Through the walk's right part only (16 states): probabilities strictly in (0, 1).
    avoid = np.ones(n, dtype=bool)
    avoid[16] = False
    reach = kernels.until_probs(P, avoid, target, workspace=workspace)
    assert contains(reach, ref.until(P, avoid, target))
    assert reach.precise_states().all()
    assert contains(kernels.until_probs(P, everywhere, target,
                                        workspace=workspace), ref.until(P, everywhere, target))


def _grid(n: int) -> sp.csr_matrix:
    """The bench's drifting walk on an n-by-n grid (one big SCC), goal at the corner."""
    x, y = np.divmod(np.arange(n * n), n)
    moves = ((0.4, np.minimum(x + 1, n - 1), y), (0.3, x, np.minimum(y + 1, n - 1)),
             (0.2, np.maximum(x - 1, 0), y), (0.1, x, np.maximum(y - 1, 0)))
    rows = np.concatenate([np.arange(n * n)] * 4)
    cols = np.concatenate([nx * n + ny for _, nx, ny in moves])
    data = np.concatenate([np.full(n * n, p) for p, _, _ in moves])
    P = sp.lil_matrix(sp.csr_matrix((data, (rows, cols)), shape=(n * n, n * n)))
    P[n * n - 1] = 0
    P[n * n - 1, n * n - 1] = 1.0
    return sp.csr_matrix(P)


@pytest.mark.parametrize("limit", [10**6, 30])
def test_grid_walk_by_lu_and_by_krylov(monkeypatch: pytest.MonkeyPatch, limit: int) -> None:
    """Both large-component methods agree with a dense solve and certify it."""
    monkeypatch.setattr(scc, "BLOCK_LIMIT", 8)
    monkeypatch.setattr(scc, "LU_LIMIT", limit)
    monkeypatch.setattr(scc, "ENVELOPE_LIMIT", 0)
    P = _grid(12)
    n = P.shape[0]
    target = np.zeros(n, dtype=bool)
    target[-1] = True
    found = kernels.reach_rewards(P, np.ones(n), target, workspace=Workspace())
    dense = np.eye(n - 1) - P.toarray()[:-1, :-1]
    expected = np.linalg.solve(dense, np.ones(n - 1))
    assert np.allclose(found.value[:-1], expected, rtol=1e-12)
    assert np.all(found.lower <= found.value) and np.all(found.value <= found.upper)
    assert found.precise_states().all()


def test_krylov_solver_solves_a_large_block(monkeypatch: pytest.MonkeyPatch) -> None:
    P = _grid(15)
    A = sp.csc_matrix(sp.eye(P.shape[0] - 1) - P[:-1, :-1])
    b = np.linspace(1.0, 3.0, A.shape[0])
    x = scc.krylov_solver(A)(b)
    assert np.max(np.abs(A @ x - b)) <= 1e-11 * np.max(np.abs(b))


def test_factorization_keeps_float64_and_residue() -> None:
    """The extended diagonal survives in the residue: a self-loop of 1 - 1e-17 is
    1 in float64, yet the stored system is the exact one."""
    P = matrix({0: {0: 1 - 2.0**-60, 1: 2.0**-60}}, 2)
    A64, residue, _ = linalg.restricted_parts(P, np.array([True, False]))
    assert A64.dtype == np.float64 and residue.dtype == np.longdouble
    # 1 - P_00 is read as the leaving probability 2^-60: exact in float64 already.
    assert A64[0, 0] == 2.0**-60 and residue.nnz == 0
    system = linalg.Factorization(A64, residue)
    x = system.solve(np.array([2.0**-60], dtype=np.longdouble))
    assert x[0] == 1.0


def _well_mixed(n: int, degree: int, seed: int) -> sp.csr_matrix:
    """A dense component: every state moves to *degree* random states (dyadic
    weights) and to the goal (state *n*) with probability 1/64, as Herman's ring does."""
    rng = np.random.default_rng(seed)
    rows: dict[int, dict[int, float]] = {n: {n: 1.0}}
    for s in range(n):
        row: dict[int, float] = {n: 1 / 64}
        for t in rng.choice(n, size=degree, replace=False):
            row[int(t)] = row.get(int(t), 0.0) + (63 / 64) / degree
        rows[s] = row
    return matrix(rows, n + 1)


def _dense_reference(P: sp.csr_matrix, rewards: np.ndarray, n: int) -> np.ndarray:
    """Expected rewards to the goal by LAPACK on the dense system (an independent solver)."""
    A = np.eye(n) - P[:n, :n].toarray()
    return np.asarray(np.linalg.solve(A, rewards[:n]))


@pytest.mark.parametrize("krylov_fails", [False, True])
def test_dense_components_go_to_krylov_first(monkeypatch: pytest.MonkeyPatch,
                                             krylov_fails: bool) -> None:
    """A 600-state component with 32 successors per state is solved by Jacobi
    Krylov (its LU would fill in densely); where Krylov falls short, by the LU."""
    n = 600
    P = _well_mixed(n, 32, seed=1)
    if krylov_fails:  # a tolerance no iteration reaches, and few iterations
        monkeypatch.setattr(scc, "KRYLOV_MAXITER", 1)
        monkeypatch.setattr(scc, "KRYLOV_RTOL", 1e-30)
    chosen: list[object] = []
    original = scc._block_solver

    def spy(block: sp.csc_matrix, *, large: bool) -> scc.Inverse | None:
        solver = original(block, large=large)
        chosen.append(solver)
        return solver

    monkeypatch.setattr(scc, "_block_solver", spy)
    rewards = (np.arange(n + 1) % 3 + 1).astype(np.float64)
    target = np.zeros(n + 1, dtype=bool)
    target[n] = True
    found = kernels.reach_rewards(P, rewards, target, workspace=Workspace())
    reference = _dense_reference(P, rewards, n)
    dense = [s for s in chosen if isinstance(s, scc._KrylovFirst)]
    assert dense
    assert bool(dense[0].lu) == krylov_fails  # the LU is made only when needed
    assert found.precise_states().all()
    assert np.allclose(found.value[:n], reference, rtol=1e-11, atol=0)
    slack = 1e-12 * np.abs(reference)  # the dense reference's own rounding
    assert np.all(found.lower[:n] <= reference + slack)
    assert np.all(reference - slack <= found.upper[:n])


def pairs_in_series(pairs: int, seed: int) -> sp.csr_matrix:
    """``I - P`` of *pairs* two-state cycles in series, each left with a dyadic
    probability towards the next pair (the last to an absorbing goal, not a row)."""
    rng = np.random.default_rng(seed)
    n = 2 * pairs
    rows: dict[int, dict[int, float]] = {}
    for k in range(pairs):
        a, b, onward = 2 * k, 2 * k + 1, 2 * k + 2
        leave = int(rng.integers(1, 4)) / 8
        rows[a] = {b: 1 - leave, **({onward: leave} if onward < n else {})}
        rows[b] = {a: 0.5, **({onward: 0.5} if onward < n else {})}
    P = matrix(rows, n)
    return sp.csr_matrix(sp.identity(n) - P)


def test_a_long_run_of_small_components_is_factorised_in_pieces(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(scc, "RUN_LIMIT", 50)
    A = pairs_in_series(200, seed=3)
    found = scc.components(A)
    assert found is not None
    pieces = scc.segments(found)
    assert len(pieces) == 8 and not any(large for _, _, large in pieces)
    assert [lo for lo, _, _ in pieces] == [0, 50, 100, 150, 200, 250, 300, 350]
    assert pieces[-1][1] == 400
    inverse = scc.segmented_inverse(A, found)
    assert inverse is not None and len(inverse.parts) == 8
    b = np.random.default_rng(4).random(400)
    whole = sp.linalg.spsolve(A.tocsc(), b)
    assert np.allclose(inverse(b), whole, rtol=1e-12, atol=0)


def test_a_cut_never_splits_a_component(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(scc, "RUN_LIMIT", 51)  # odd: 51 falls inside a pair
    found = scc.components(pairs_in_series(200, seed=5))
    assert found is not None
    starts = set(found.starts.tolist())
    assert all(lo in starts and hi in starts for lo, hi, _ in scc.segments(found))
