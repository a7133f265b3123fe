"""The one-substitution certification path (certify.quick_certificate, until._quick).

The quick path only runs on systems of at least ``systems.QUICK_MIN_STATES``
unknowns; these tests lower that threshold to 0 so that small chains, whose exact
answers are computed independently in Fractions (tests/checker/exact_reference.py),
go through it. Every interval must contain the exact value, whichever path certified it.
"""

from __future__ import annotations

from collections.abc import Iterator
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.checker import exact_reference as ref
from tests.checker.chains import draw_stochastic, matrix
from veribattery.checker import Workspace, certify, kernels
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.kernels import systems
from veribattery.pipeline import check_prism_file

DATA = Path(__file__).resolve().parent.parent / "data"


def contains(found: Bounds, exact: list[Fraction]) -> bool:
    return all(Fraction(float(lo)) <= v <= Fraction(float(hi))
               for lo, hi, v in zip(found.lower, found.upper, exact, strict=True))


@pytest.fixture
def quick_everywhere(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[bool]]:
    """Every system tries the quick path; yields a log of its outcomes (True: certified)."""
    monkeypatch.setattr(systems, "QUICK_MIN_STATES", 0)
    outcomes: list[bool] = []
    original = certify.quick_certificate

    def logged(*args: object) -> tuple[np.ndarray, np.ndarray] | None:
        found = original(*args)  # type: ignore[arg-type]
        outcomes.append(found is not None)
        return found

    monkeypatch.setattr(certify, "quick_certificate", logged)
    yield outcomes


# --- directed rounding ---------------------------------------------------------------


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=-1e300, max_value=1e300))
def test_step_up_and_down_pass_the_neighbours(c: float) -> None:
    # (near the largest float the bound overflows to inf: still a bound, not tested here)
    array = np.array([c])
    up, down = float(certify.step_up(array)[0]), float(certify.step_down(array)[0])
    assert up >= float(np.nextafter(c, np.inf))
    assert down <= float(np.nextafter(c, -np.inf))
    # At most two floats away (Rump et al. 2009): tight enough to certify 1e-9.
    assert up <= float(np.nextafter(np.nextafter(c, np.inf), np.inf))
    assert down >= float(np.nextafter(np.nextafter(c, -np.inf), -np.inf))


def test_step_rounding_on_subnormals_and_zero() -> None:
    tiny = np.array([0.0, 5e-324, -5e-324, 2.0**-1022])
    assert np.all(certify.step_up(tiny) > tiny)
    assert np.all(certify.step_down(tiny) < tiny)


# --- the path itself ------------------------------------------------------------------


def _chain(n: int) -> sp.csr_matrix:
    """A birth-death chain towards n-1 with a self-loop near 1 and a 1e-12 exit."""
    rows: dict[int, dict[int, float]] = {0: {0: 1 - 1e-12, 1: 1e-12}}
    for s in range(1, n - 1):
        rows[s] = {s - 1: 0.3, s + 1: 0.6, s: 0.1}
    return matrix(rows, n)


def test_quick_path_certifies_a_chain_with_exact_answers(quick_everywhere: list[bool]) -> None:
    n = 12
    P = _chain(n)
    target = np.zeros(n, dtype=bool)
    target[n - 1] = True
    everywhere = np.ones(n, dtype=bool)
    workspace = Workspace()
    probs = kernels.until_probs(P, everywhere, target, workspace=workspace)
    assert contains(probs, ref.until(P, everywhere, target))
    rewards = np.arange(n, dtype=np.float64)
    found = kernels.reach_rewards(P, rewards, target, workspace=workspace)
    assert contains(found, ref.reach_rewards(P, rewards, target))
    assert found.precise_states().all()
    assert quick_everywhere and quick_everywhere[-1]  # the rewards took the quick path


def test_failed_quick_test_falls_back_and_stays_certified(
        quick_everywhere: list[bool]) -> None:
    # Haddad-Monmege: condition number ~2^N, the unrefined solution is far off;
    # its certified interval is far too wide, so the escalation must take over and
    # still find exactly 0.7 (the unrefined float answer is nowhere near it).
    run = check_prism_file(DATA / "haddad_monmege.prism", props_source="P=? [ F x=0 ]",
                           constants={"N": 60, "p": 0.7})
    result = run.results[0]
    assert result.value == 0.7
    assert Fraction(result.lower) <= Fraction(0.7) <= Fraction(result.upper)
    assert result.precise and quick_everywhere  # the quick path was tried first


def test_bound_at_the_trivial_value_needs_no_test() -> None:
    # Probabilities within an ulp or two of 1: the upper candidate sits at the
    # ceiling 1, whose enclosure is above 1 -- the pair is still accepted (F(u) <=
    # F(1) <= 1 exactly) and still contains the exact values.
    n = 6
    target = n - 1
    P = matrix({s: {target: 0.75, s + 1: 0.25 - 2.0**-50, 0: 2.0**-50}
                for s in range(n - 1)}, n)
    maybe = np.arange(n) != target
    known = (~maybe).astype(np.float64)
    rows = sp.csr_matrix(P[np.flatnonzero(maybe)])
    F = certify.AffineMap.of(rows, np.flatnonzero(maybe), known, known, None)
    exact = ref.until(P, np.ones(n, dtype=bool), ~maybe)[: n - 1]
    x = np.array([float(v) for v in exact])
    found = certify.quick_certificate(F, x, lambda v: v * n, np.zeros(n - 1), np.ones(n - 1))
    assert found is not None
    assert np.any(found[1] == 1.0)  # the rule was needed
    assert contains(Bounds.around(x, *found), exact)


def test_properties_on_one_state_set_share_the_row_data() -> None:
    n = 5
    P = _chain(n)
    target = np.zeros(n, dtype=bool)
    target[n - 1] = True
    maybe = ~target
    system = systems._system(P, maybe, workspace=Workspace())
    zeros = np.zeros(n)
    first = system.affine(zeros, zeros, np.ones(n - 1))
    second = system.affine(zeros, zeros, np.arange(n - 1, dtype=np.float64))
    assert second.rows is first.rows and second.leave_lower is first.leave_lower
    assert second.offset is not None and second.offset[1] == 1.0


# --- property-based: random DTMCs through the quick path --------------------------------


@st.composite
def chains(draw: st.DrawFn) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    n = draw(st.integers(2, 9))
    P = draw_stochastic(draw, n)
    flags = st.lists(st.booleans(), min_size=n, max_size=n)
    rewards = np.array(draw(st.lists(st.integers(0, 5), min_size=n, max_size=n)), dtype=float)
    return P, np.array(draw(flags)), rewards


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(chains())
def test_random_chains_quick_path_contains_exact(
        quick_everywhere: list[bool],
        case: tuple[sp.csr_matrix, np.ndarray, np.ndarray]) -> None:
    P, target, rewards = case
    everywhere = np.ones(P.shape[0], dtype=bool)
    workspace = Workspace()
    probs = kernels.until_probs(P, everywhere, target, workspace=workspace)
    assert contains(probs, ref.until(P, everywhere, target))
    assert probs.precise_states().all()
    found = kernels.reach_rewards(P, rewards, target, workspace=workspace)
    finite = np.isfinite(found.value)
    exact = ref.reach_rewards(P, rewards, target)
    assert contains(Bounds(*(v[finite] for v in (found.value, found.lower, found.upper))),
                    [e for e, f in zip(exact, finite, strict=True) if f])
    assert found.precise_states().all()
