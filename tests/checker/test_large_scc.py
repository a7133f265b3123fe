"""The large-component path of checker/linalg/scc.py: multigrid-preconditioned Krylov, certified.

Module constants are lowered with monkeypatch so that models of a few thousand
states (or a few dozen, where exact Fraction references are cheap) take the
path that 10^6-state meshes take by default.
"""

from __future__ import annotations

from collections.abc import Callable
from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401 -- sp.linalg below

from tests.checker import exact_reference as ref
from tests.checker.test_scc_solve import _grid, ring_then_walk
from veribattery.checker import Workspace, certify, kernels, linalg
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.kernels import systems
from veribattery.checker.linalg import scc

GRID = """dtmc
const int N = {n};
module walker
  x : [0..N-1] init 0;
  y : [0..N-1] init 0;
  [] !(x=N-1 & y=N-1) -> 0.4:(x'=min(x+1,N-1)) + 0.3:(y'=min(y+1,N-1))
                       + 0.2:(x'=max(x-1,0)) + 0.1:(y'=max(y-1,0));
endmodule
label "goal" = x=N-1 & y=N-1;
label "corner" = x=N-1 & y=0;
rewards "steps"
  true : 1;
endrewards
"""


@pytest.fixture
def krylov_calls(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Every component above 8 states goes to the Krylov path; returns its block sizes."""
    monkeypatch.setattr(scc, "BLOCK_LIMIT", 8)
    monkeypatch.setattr(scc, "LU_LIMIT", 8)
    monkeypatch.setattr(scc, "ENVELOPE_LIMIT", 0)
    calls: list[int] = []
    original = scc.krylov_solver

    def spy(block: sp.csc_matrix) -> scc.Inverse:
        calls.append(block.shape[0])
        return original(block)

    monkeypatch.setattr(scc, "krylov_solver", spy)
    return calls


def contains(found: Bounds, exact: list[Fraction]) -> bool:
    """Every exact value inside its state's certified interval (compared exactly)."""
    return all(Fraction(float(lo)) <= v <= Fraction(float(hi))
               for lo, hi, v in zip(found.lower, found.upper, exact, strict=True))


@pytest.mark.parametrize("seed", range(3))
def test_krylov_path_contains_the_exact_values(krylov_calls: list[int], seed: int) -> None:
    P = ring_then_walk(12, 24, seed=seed)
    n = P.shape[0]
    target = np.zeros(n, dtype=bool)
    target[-1] = True
    rewards = (np.arange(n) % 3 + 1) / 4
    workspace = Workspace()
    found = kernels.reach_rewards(P, rewards, target, workspace=workspace)
    assert sorted(krylov_calls) == [12, 24]
    assert contains(found, ref.reach_rewards(P, rewards, target))
    assert found.precise_states().all()
    avoid = np.ones(n, dtype=bool)
    avoid[20] = False
    reach = kernels.until_probs(P, avoid, target, workspace=workspace)
    assert contains(reach, ref.until(P, avoid, target))
    assert reach.precise_states().all()


def _grid_system_on_krylov() -> tuple[sp.csr_matrix, scc.Segmented]:
    """The 10x10 grid's system (all but the corner unknown) and its Krylov inverse."""
    P = _grid(10)
    maybe = np.ones(P.shape[0], dtype=bool)
    maybe[-1] = False
    A64, _, _ = linalg.restricted_parts(P, maybe)
    found = scc.components(A64)
    assert found is not None
    inverse = scc.segmented_inverse(A64, found)
    assert inverse is not None and inverse.iterative
    return A64, inverse


def test_krylov_path_marks_the_factorization_iterative(krylov_calls: list[int]) -> None:
    A64, inverse = _grid_system_on_krylov()
    b = np.linspace(1.0, 2.0, A64.shape[0])
    assert np.max(np.abs(A64 @ inverse(b) - b)) <= 1e-10


@pytest.mark.parametrize(("side", "exact"), [(12, True), (50, False)])
def test_grid_against_storm(krylov_calls: list[int], side: int, exact: bool) -> None:
    """A 2-D grid (one component) against Storm: its exact engine on 144 states (the
    interval must contain Storm's rational answer), its float engine (relative
    precision 1e-6) on 2,500 states."""
    pytest.importorskip("stormpy")
    from tests.storm_oracle import compare, run_storm
    from veribattery.pipeline import check_prism_file

    model = GRID.format(n=side)
    props = 'R{"steps"}=? [ F "goal" ];\nP=? [ !"corner" U "goal" ];\n'
    run = check_prism_file(model, props_source=props)
    assert krylov_calls and max(krylov_calls) >= side * side - 2
    storm = run_storm(model, props, exact=exact)
    tolerance = 1e-9 if exact else 1e-5
    assert compare(run, storm, ["steps", "avoid"], rtol=tolerance, atol=1e-12) == []
    for result, values in zip(run.results, storm.values, strict=True):
        assert result.precise
        if exact:  # Storm's rational, rounded to nearest: inside the float interval too
            assert result.lower <= float(values[storm.initial[0]]) <= result.upper


def test_thin_components_keep_the_lu(monkeypatch: pytest.MonkeyPatch) -> None:
    """The envelope estimate: a long chain or ring has small factors, a grid does not."""
    monkeypatch.setattr(scc, "ENVELOPE_LIMIT", 100_000)
    n = 5_000
    chain = sp.diags([np.full(n - 1, -0.5), np.ones(n), np.full(n - 1, -0.4)], [-1, 0, 1])
    assert scc._thin(sp.csc_matrix(chain))
    ring = sp.lil_matrix(chain)
    ring[0, n - 1] = -0.05
    ring[n - 1, 0] = -0.05
    assert scc._thin(sp.csc_matrix(ring))
    grid = sp.eye(70 * 70) - _grid(70)
    assert not scc._thin(sp.csc_matrix(grid))


def test_restricted_parts_match_the_dense_reference() -> None:
    """The system built from the rows' arrays equals ``I - P_mm`` with the diagonal
    read as the probability of leaving (within the extended residue)."""
    rng = np.random.default_rng(7)
    for _ in range(40):
        n = int(rng.integers(2, 30))
        P = sp.random(n, n, density=0.3, random_state=rng, format="csr")
        P.data = rng.choice([0.1, 0.25, 1 / 3, 1e-12, 1 - 1e-12, 0.0], P.nnz)
        maybe = rng.random(n) < 0.7
        A64, residue, rows = linalg.restricted_parts(P, maybe)
        idx = np.flatnonzero(maybe)
        dense = P.toarray()
        assert np.array_equal(rows.toarray(), dense[idx])
        inner = dense[np.ix_(idx, idx)]
        off = A64.toarray() - np.diag(A64.diagonal())
        assert np.array_equal(off, -(inner - np.diag(np.diag(inner))))
        exact = [sum((Fraction(float(v)) for j, v in enumerate(dense[i]) if j != i), Fraction(0))
                 for i in idx]
        extended = A64.diagonal().astype(np.longdouble) + residue.diagonal()
        assert all(abs(Fraction(*e.as_integer_ratio()) - x) <= Fraction(1, 2**55) for e, x in
                   zip(extended, exact, strict=True))
        assert A64.has_sorted_indices and A64.dtype == np.float64


@pytest.fixture
def quick_only(krylov_calls: list[int], monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The Krylov path with the quick certificate on every system; the long way fails
    the test. Returns which margin each certificate used ("solve" or "proportional")."""
    monkeypatch.setattr(systems, "QUICK_MIN_STATES", 1)

    def no_long_way(*args: object, **kwargs: object) -> None:
        raise AssertionError("the quick certificate should have been enough")

    monkeypatch.setattr(certify, "certify_fixpoint", no_long_way)
    used: list[str] = []
    original_margin = scc.Segmented.margin
    original_for = linalg.Factorization.margins_for

    def margin(self: scc.Segmented, v: np.ndarray) -> np.ndarray:
        used.append("solve")
        return original_margin(self, v)

    def margins_for(self: linalg.Factorization, b: np.ndarray, x: np.ndarray
                    ) -> list[Callable[[np.ndarray], np.ndarray | None]]:
        chosen = original_for(self, b, x)
        if chosen[0].__name__ == "proportional":
            used.append("proportional")
        return chosen

    monkeypatch.setattr(scc.Segmented, "margin", margin)
    monkeypatch.setattr(linalg.Factorization, "margins_for", margins_for)
    return used


@pytest.mark.parametrize("side", [5, 6])
def test_quick_certificate_on_the_krylov_path(quick_only: list[str], side: int) -> None:
    """One Krylov solve and the quick certificate: positive rewards take the margin
    proportional to the solution (no second solve), probabilities a loose solve of
    the lifted defect; the intervals contain the exact rationals either way."""
    P = _grid(side)
    n = P.shape[0]
    target = np.zeros(n, dtype=bool)
    target[-1] = True
    rewards = (np.arange(n) % 3 + 1) / 4
    workspace = Workspace()
    found = kernels.reach_rewards(P, rewards, target, workspace=workspace)
    assert contains(found, ref.reach_rewards(P, rewards, target))
    assert found.precise_states().all()
    assert quick_only == ["proportional"]
    used = len(quick_only)
    avoid = np.ones(n, dtype=bool)
    avoid[n // 2] = False
    reach = kernels.until_probs(P, avoid, target, workspace=workspace)
    assert contains(reach, ref.until(P, avoid, target))
    assert reach.precise_states().all()
    assert quick_only[used:] == ["solve"]


def test_grid_quick_path_against_exact_storm(quick_only: list[str]) -> None:
    """The bench's drifting grid (one component, 144 states) through the quick Krylov
    path: Storm's exact answers lie inside the intervals."""
    pytest.importorskip("stormpy")
    from tests.storm_oracle import run_storm
    from veribattery.pipeline import check_prism_file

    model = GRID.format(n=12)
    props = 'R{"steps"}=? [ F "goal" ];\nP=? [ !"corner" U "goal" ];\n'
    run = check_prism_file(model, props_source=props)
    storm = run_storm(model, props, exact=True)
    assert quick_only == ["proportional", "solve"]
    for result, values in zip(run.results, storm.values, strict=True):
        exact = Fraction(values[storm.initial[0]])
        assert result.precise
        assert Fraction(result.lower) <= exact <= Fraction(result.upper)


def test_lifted_loose_margin_covers_a_defect_with_zeros(krylov_calls: list[int]) -> None:
    """Segmented.margin solves loosely for a lifted right-hand side: the result is
    at least the exact A^-1 v (up to the loose tolerance) even where v is 0."""
    A64, inverse = _grid_system_on_krylov()
    v = np.zeros(A64.shape[0])
    v[::7] = 1e-9
    margin = inverse.margin(v)
    exact = sp.linalg.spsolve(sp.csc_matrix(A64), v)
    assert np.all(margin >= exact)
    assert np.all(margin > 0)
