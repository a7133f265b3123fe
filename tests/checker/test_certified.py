"""Certified bounds: the exact rational answer lies inside every reported interval.

References are independent (tests/checker/exact_reference.py: dense Fraction
arithmetic on the float64 entries), on models built to defeat float64 solvers.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.checker import exact_reference as ref
from tests.checker.chains import draw_stochastic, matrix
from veribattery.checker import Workspace, kernels
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.result import CheckResult
from veribattery.config.schema import parse_requirement
from veribattery.lang.nodes import BoolLit, Property
from veribattery.mission.report import _judge
from veribattery.pipeline import check_prism_file

DATA = Path(__file__).resolve().parent.parent / "data"


def contains(found: Bounds, exact: list[Fraction]) -> bool:
    """Every exact value inside its state's certified interval (compared exactly)."""
    return all(Fraction(float(lo)) <= v <= Fraction(float(hi))
               for lo, hi, v in zip(found.lower, found.upper, exact, strict=True))


# --- Haddad & Monmege ---------------------------------------------------------------


@pytest.mark.parametrize("n", [2, 20, 100, 300])
def test_haddad_monmege_is_exactly_p(n: int) -> None:
    run = check_prism_file(DATA / "haddad_monmege.prism",
                           props_source=DATA / "haddad_monmege.props",
                           constants={"N": n, "p": 0.7})
    reach, by_label, decided = run.results
    assert run.dtmc.num_states == 2 * n + 1
    # 1 - p is exact in float64, so the exact answer is the float 0.7 itself.
    for result in (reach, by_label):
        assert result.value == 0.7
        assert result.lower is not None and result.upper is not None
        assert Fraction(result.lower) <= Fraction(0.7) <= Fraction(result.upper)
        assert result.precise
    assert decided.value is True


def test_haddad_monmege_every_state_against_fractions() -> None:
    run = check_prism_file(DATA / "haddad_monmege.prism", props_source="P=? [ F x=0 ]",
                           constants={"N": 25, "p": 0.7})
    dtmc = run.dtmc
    target = dtmc.column("x") == 0
    exact = ref.until(dtmc.transitions, np.ones(dtmc.num_states, dtype=bool), target)
    found = run.results[0].bounds
    assert found is not None
    assert contains(found, exact)
    assert found.precise_states().all()


# --- extreme probabilities ----------------------------------------------------------


@pytest.mark.parametrize("eps", [1e-12, 1e-6, 0.25])
def test_tiny_and_near_one_probabilities(eps: float) -> None:
    # 0 loops with 1 - 2 eps, leaves to 1 (goal) or 2 (fail) with eps each;
    # 3 reaches 0 with probability 1 - 1e-12 and 1 directly with 1e-12.
    P = matrix({0: {0: 1 - 2 * eps, 1: eps, 2: eps}, 3: {0: 1 - 1e-12, 1: 1e-12}}, 4)
    target = np.array([False, True, False, False])
    everywhere = np.ones(4, dtype=bool)
    found = kernels.until_probs(P, everywhere, target, workspace=Workspace())
    assert contains(found, ref.until(P, everywhere, target))
    assert found.precise_states().all()
    # The self-loop is read as 1 - (leaving probability): exactly 1/2 from state 0.
    assert found.value[0] == 0.5


def test_rewards_with_near_one_self_loop() -> None:
    P = matrix({0: {0: 1 - 1e-12, 1: 1e-12}}, 2)
    found = kernels.reach_rewards(P, np.array([1.0, 0.0]), np.array([False, True]),
                                  workspace=Workspace())
    assert found.lower[0] <= 1e12 <= found.upper[0]
    assert found.precise_states().all()


def _stiff_chain(seed: int, n: int) -> sp.csr_matrix:
    """A random chain mixing probabilities of order 1 and 1e-12 ... 1e-3."""
    rng = np.random.default_rng(seed)
    rows: dict[int, dict[int, float]] = {}
    for s in range(n - 2):
        succ = rng.choice(n, size=3, replace=False)
        w = np.array([1.0, 10.0 ** -rng.integers(3, 13), 10.0 ** -rng.integers(3, 13)])
        rows[s] = {int(t): float(v) for t, v in zip(succ, w / w.sum(), strict=True)}
    return matrix(rows, n)


@pytest.mark.parametrize("seed", range(6))
def test_stiff_random_chains(seed: int) -> None:
    n = 25
    P = _stiff_chain(seed, n)
    target = np.zeros(n, dtype=bool)
    target[n - 1] = True
    everywhere = np.ones(n, dtype=bool)
    workspace = Workspace()
    found = kernels.until_probs(P, everywhere, target, workspace=workspace)
    assert contains(found, ref.until(P, everywhere, target))
    rewards = np.ones(n)
    got = kernels.reach_rewards(P, rewards, target, workspace=workspace)
    exact = ref.reach_rewards(P, rewards, target)
    finite = np.isfinite(got.value)
    assert contains(Bounds(*(v[finite] for v in (got.value, got.lower, got.upper))),
                    [e for e, f in zip(exact, finite, strict=True) if f])


# --- property-based: random DTMCs ----------------------------------------------------


@st.composite
def chains(draw: st.DrawFn) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray, np.ndarray, int]:
    """A random stochastic matrix (weights 1..9 normalised in float64), masks, rewards, k."""
    n = draw(st.integers(2, 9))
    P = draw_stochastic(draw, n)
    flags = st.lists(st.booleans(), min_size=n, max_size=n)
    remain, target = np.array(draw(flags)), np.array(draw(flags))
    rewards = np.array(draw(st.lists(st.integers(0, 5), min_size=n, max_size=n)), dtype=float)
    return P, remain, target, rewards, draw(st.integers(0, 8))


@settings(max_examples=80, deadline=None)
@given(chains())
def test_until_interval_contains_exact(case: tuple) -> None:  # type: ignore[type-arg]
    P, remain, target, _, _ = case
    found = kernels.until_probs(P, remain, target, workspace=Workspace())
    assert contains(found, ref.until(P, remain, target))
    assert found.precise_states().all()  # small random chains are well conditioned


@settings(max_examples=80, deadline=None)
@given(chains())
def test_reach_rewards_interval_contains_exact(case: tuple) -> None:  # type: ignore[type-arg]
    P, _, target, rewards, _ = case
    found = kernels.reach_rewards(P, rewards, target, workspace=Workspace())
    exact = ref.reach_rewards(P, rewards, target)
    finite = np.isfinite(found.value)
    assert np.array_equal(found.lower[~finite], found.upper[~finite])
    assert contains(Bounds(*(v[finite] for v in (found.value, found.lower, found.upper))),
                    [e for e, f in zip(exact, finite, strict=True) if f])
    assert found.precise_states().all()


@settings(max_examples=40, deadline=None)
@given(chains())
def test_step_bounded_intervals_contain_exact(case: tuple) -> None:  # type: ignore[type-arg]
    P, remain, target, rewards, k = case
    n = P.shape[0]
    hit = [Fraction(int(t)) for t in target]
    inside = remain & ~target
    moving = sp.csr_matrix(sp.diags(inside.astype(float)) @ P)
    assert contains(kernels.bounded_until_probs(P, remain, target, k),
                    ref.step_power(moving, hit, hit, k))
    offset = [Fraction(float(r)) for r in rewards]
    assert contains(kernels.cumulative_rewards(P, rewards, k),
                    ref.step_power(P, [Fraction(0)] * n, offset, k))
    assert contains(kernels.instantaneous_rewards(P, rewards, k),
                    ref.step_power(P, offset, [Fraction(0)] * n, k))


# --- decisions from intervals ----------------------------------------------------------


def test_compare_is_tri_state() -> None:
    b = Bounds(np.array([0.5, 0.5, 0.9]), np.array([0.4, 0.5, 0.89]),
               np.array([0.6, 0.5, 0.91]))
    holds, undecided = b.compare(">=", 0.5)
    assert holds.tolist() == [False, True, True]
    assert undecided.tolist() == [True, False, False]


def _result(value: float, lower: float, upper: float) -> CheckResult:
    prop = Property(BoolLit(True), name="p_success")
    return CheckResult(prop, np.array([value]), value, 0.0, lower, upper, False)


@pytest.mark.parametrize(("lower", "upper", "holds", "decided"), [
    (0.9991, 0.9995, True, True),
    (0.99, 0.998, False, True),
    (0.998, 0.9992, False, False),
])
def test_requirement_judged_from_interval(lower: float, upper: float, holds: bool,
                                          decided: bool) -> None:
    requirement = parse_requirement("p_success >= 0.999")
    outcome = _judge(requirement, {"p_success": _result((lower + upper) / 2, lower, upper)})
    assert (outcome.holds, outcome.decided) == (holds, decided)


# --- SCC-wise LU ------------------------------------------------------------------------


def _chain_of_cycles(blocks: int, size: int, seed: int) -> sp.csr_matrix:
    """Cycles of *size* states, each leaking into the next cycle and to an exit state."""
    rng = np.random.default_rng(seed)
    n = blocks * size + 1
    rows: dict[int, dict[int, float]] = {}
    for s in range(n - 1):
        block, pos = divmod(s, size)
        around = block * size + (pos + 1) % size
        onward = min((block + 1) * size + int(rng.integers(size)), n - 1)
        w = rng.random(3) + 0.1
        w /= w.sum()
        rows[s] = {around: float(w[0]), onward: float(w[1]), n - 1: float(w[2])}
    return matrix(rows, n)


def test_block_lu_matches_dense_solve_and_certifies() -> None:
    from veribattery.checker import linalg
    from veribattery.checker.linalg import scc

    P = _chain_of_cycles(10, 4, seed=1)
    n = P.shape[0]
    maybe = np.ones(n, dtype=bool)
    maybe[-1] = False
    A, _ = linalg.restricted_matrix(P, maybe)
    A64 = sp.csr_matrix(A.astype(np.float64))
    found = scc.components(A64)
    assert found is not None and found.largest == 4  # 10 SCCs of 4 states
    inverse = scc.segmented_inverse(A64, found)
    assert inverse is not None
    b = np.linspace(1.0, 2.0, n - 1)
    assert np.allclose(inverse(b), np.linalg.solve(A64.toarray(), b), rtol=1e-12)
    target = ~maybe
    everywhere = np.ones(n, dtype=bool)
    workspace = Workspace()
    found = kernels.reach_rewards(P, np.ones(n), target, workspace=workspace)
    assert contains(found, ref.reach_rewards(P, np.ones(n), target))
    assert found.precise_states().all()
    assert contains(kernels.until_probs(P, everywhere, target,
                                        workspace=workspace), ref.until(P, everywhere, target))


# --- output ---------------------------------------------------------------------------


@pytest.mark.parametrize(("value", "lower", "upper", "text"), [
    (0.7, 0.7, 0.7, "0.7"),
    (4796.963222950812, 4796.963222923, 4796.963222978, "4796.96322295 ± 2.8e-08"),
    (4796.963222950812, 4796.963222947433, 4796.963222954192, "4796.96322295"),
    (0.5, 0.5 - 1e-17, 0.5 + 1e-17, "0.5"),
    (0.0, 0.0, 1.0, "0 ± 1"),
])
def test_table_shows_error_when_visible(value: float, lower: float, upper: float,
                                        text: str) -> None:
    from veribattery.cli.output import format_result, result_bounds

    result = _result(value, lower, upper)
    assert format_result(result) == text
    assert result_bounds(result) == [lower, upper]
