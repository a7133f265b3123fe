"""How far a long solve is, told to whoever listens to the workspace's monitor.

Every solver reports at its own grain (a segment of an SCC-wise solve, an iteration
of the iterative fallback, before and after a solve in one call), never per state;
and listening changes no value: the bounds are the same to the last bit.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker.test_large_systems import _forward_chain, _staged
from veribattery.checker import Workspace, kernels
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.linalg import SolveMonitor, factorization
from veribattery.checker.linalg.iterative import ITERATIVE_MAXITER

Report = tuple[int, int, str]


def _until(P: sp.csr_matrix, goal: int, heard: list[Report] | None
           ) -> tuple[Bounds, str | None]:
    """``P(F goal)`` with the monitor listened to (into *heard*) or not (None)."""
    n = P.shape[0]
    target = np.zeros(n, dtype=bool)
    target[goal] = True
    workspace = Workspace()
    listener = None if heard is None else (lambda *report: heard.append(report))
    with workspace.monitor.listening(listener):
        bounds = kernels.until_probs(P, np.ones(n, dtype=bool), target, workspace=workspace)
    (system,) = workspace.kernels.of(P).systems.values()
    return bounds, system.factorization.method


def _same(a: Bounds, b: Bounds) -> bool:
    return all(np.array_equal(x, y) for x, y in
               ((a.value, b.value), (a.lower, b.lower), (a.upper, b.upper)))


@pytest.mark.parametrize(("limit", "method", "segments"),
                         [(None, "segmented", 1), (100, "topological", 2)],
                         ids=["segmented", "topological"])
def test_an_scc_wise_solve_reports_after_each_segment(
        monkeypatch: pytest.MonkeyPatch, limit: int | None, method: str, segments: int) -> None:
    P, _, goal, exact = _staged()
    if limit is not None:
        monkeypatch.setattr(factorization, "DIRECT_LIMIT", limit)
    heard: list[Report] = []
    bounds, used = _until(P, goal, heard)
    assert used == method
    unknowns = P.shape[0] - 2  # all but fail and goal
    # One solve: segments in order, rising to all the unknowns; several solves
    # (refinement) start again from the first segment.
    assert heard and {unit for _, _, unit in heard} == {"states"}
    assert {total for _, total, _ in heard} == {unknowns}
    ends = [i for i, (done, _, _) in enumerate(heard) if done == unknowns]
    first = heard[:ends[0] + 1]
    # Below the limit small components go in runs of up to 4,096 states (one here);
    # above it the walk (80 states) is a segment of its own, then singles and pairs.
    assert len(first) >= segments
    assert [done for done, _, _ in first] == sorted({done for done, _, _ in first})
    quiet, _ = _until(P, goal, None)
    assert _same(bounds, quiet)
    assert Fraction(float(bounds.lower[0])) <= exact <= Fraction(float(bounds.upper[0]))


def test_a_substitution_reports_its_size_before_and_after() -> None:
    P, goal, _ = _forward_chain(500)
    heard: list[Report] = []
    bounds, used = _until(P, goal, heard)
    assert used == "substitution"
    assert heard and len(heard) % 2 == 0
    assert heard[:2] == [(0, 500, "states"), (500, 500, "states")]
    assert _same(bounds, _until(P, goal, None)[0])


def test_the_iterative_fallback_reports_its_iterations(monkeypatch: pytest.MonkeyPatch) -> None:
    P, _, goal, exact = _staged()
    monkeypatch.setattr(factorization, "DIRECT_LIMIT", 70)  # the walk (80) is too large
    heard: list[Report] = []
    bounds, used = _until(P, goal, heard)
    assert used is None  # no direct solver: BiCGSTAB (then GMRES) did it
    iterations = [done for done, total, unit in heard
                  if unit == "iterations" and total == ITERATIVE_MAXITER]
    assert iterations[:3] == [1, 2, 3]
    assert _same(bounds, _until(P, goal, None)[0])
    assert Fraction(float(bounds.lower[0])) <= exact <= Fraction(float(bounds.upper[0]))


def test_a_monitor_relays_to_the_listener_of_the_moment_only() -> None:
    monitor = SolveMonitor()
    outer: list[Report] = []
    inner: list[Report] = []
    monitor(1, 2)  # no one listens: dropped
    assert not monitor.heard
    with monitor.listening(lambda *r: outer.append(r)):
        monitor(1, 4)
        with monitor.listening(lambda *r: inner.append(r)):
            monitor(2, 4, "iterations")
        monitor(3, 4)
    monitor(4, 4)
    assert outer == [(1, 4, "states"), (3, 4, "states")]
    assert inner == [(2, 4, "iterations")]
    assert not monitor.heard


def _walk(n: int) -> sp.csr_matrix:
    """A walk on ``0..n-1`` that moves up with 1/2 and stays with 1/2; ``n-1`` absorbs."""
    rows = np.repeat(np.arange(n - 1), 2)
    cols = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1).ravel()
    P = sp.csr_matrix((np.full(rows.size, 0.5), (rows, cols)), shape=(n, n))
    return sp.csr_matrix(P + sp.csr_matrix(([1.0], ([n - 1], [n - 1])), shape=(n, n)))


def test_a_step_bounded_until_reports_each_step_and_keeps_its_bounds() -> None:
    n, k = 4, 12
    P = _walk(n)
    everywhere, goal = np.ones(n, dtype=bool), np.arange(n) == n - 1
    monitor = SolveMonitor()
    heard: list[Report] = []
    with monitor.listening(lambda *report: heard.append(report)):
        told = kernels.bounded_until_probs(P, everywhere, goal, k, progress=monitor)
    assert heard == [(step, k, "steps") for step in range(1, k + 1)]
    assert _same(told, kernels.bounded_until_probs(P, everywhere, goal, k))
    # From 0 the goal is 3 successes of a fair coin within 12 tosses.
    exact = 1 - sum(Fraction(_binomial(k, i), 2**k) for i in range(3))
    assert Fraction(float(told.lower[0])) <= exact <= Fraction(float(told.upper[0]))


def _binomial(n: int, i: int) -> int:
    from math import comb

    return comb(n, i)


def test_cumulative_and_instantaneous_rewards_report_each_step() -> None:
    P = _walk(5)
    heard: list[Report] = []
    monitor = SolveMonitor()
    with monitor.listening(lambda *report: heard.append(report)):
        kernels.cumulative_rewards(P, np.ones(5), 7, progress=monitor)
        kernels.instantaneous_rewards(P, np.arange(5.0), 3, progress=monitor)
    assert heard == [(s, 7, "steps") for s in range(1, 8)] + [(s, 3, "steps")
                                                               for s in range(1, 4)]
