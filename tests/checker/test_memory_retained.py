"""What a check keeps alive: one copy of each linear system's rows, no released matrix,
no query vectors in a kept map, a narrow state table -- and the same numbers.

Each test compares against values computed independently (a closed form or the same
check with nothing released) and measures retained memory with tracemalloc (numpy
reports its buffers to it). No timing is asserted.
"""

from __future__ import annotations

import tracemalloc
from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from veribattery.checker import Workspace, kernels, linalg
from veribattery.checker.kernels import systems
from veribattery.checker.linalg import factorization
from veribattery.explore.dtmc import DTMC, RewardVectors
from veribattery.pipeline import check_prism_file


def _forward_chain(n: int) -> sp.csr_matrix:
    """States 0..n-1: from i < n-1 one step to i+1 (probability 1/4) or to i+2 (3/4,
    or all of it to i+1 at n-2); n-1 absorbing. Acyclic: solved by substitution."""
    rows, cols, data = [], [], []
    for step, p in ((1, 0.25), (2, 0.75)):
        i = np.arange(n - 2)
        rows.append(i), cols.append(i + step), data.append(np.full(i.size, p))
    rows += [np.array([n - 2, n - 1])]
    cols += [np.array([n - 1, n - 1])]
    data += [np.array([1.0, 1.0])]
    return sp.csr_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n, n))


def _steps_exact(n: int) -> list[Fraction]:
    """Expected steps to n-1 from each state, by the recurrence, exactly."""
    e = [Fraction(0)] * n
    e[n - 2] = Fraction(1)
    for i in range(n - 3, -1, -1):
        e[i] = 1 + Fraction(1, 4) * e[i + 1] + Fraction(3, 4) * e[i + 2]
    return e


def test_released_matrix_comes_back_bit_for_bit(monkeypatch: pytest.MonkeyPatch) -> None:
    """A triangular system drops ``I - P_mm`` once the substitution is built, and makes
    the same matrix again when a refined solve asks for it."""
    monkeypatch.setattr(factorization, "RELEASE_MIN_STATES", 1)
    monkeypatch.setattr(systems, "QUICK_MIN_STATES", 1)  # certified without a refined solve
    P = _forward_chain(400)
    target = np.zeros(400, dtype=bool)
    target[-1] = True
    workspace = Workspace()
    found = kernels.reach_rewards(P, np.ones(400), target, workspace=workspace)
    system = next(iter(workspace.kernels.of(P).systems.values()))
    solver = system.factorization
    assert solver._a64 is None and solver._residue is None  # released
    fresh, residue, _ = linalg.unplanned_parts(P, system.unknowns)
    again = solver.A64  # made again on demand
    assert (again != fresh).nnz == 0 and np.array_equal(again.indices, fresh.indices)
    assert (solver.residue != residue).nnz == 0
    exact = _steps_exact(400)
    b = np.ones(399, dtype=np.longdouble)
    x = solver.solve(b)  # the refined path, on the rebuilt matrix
    assert float(abs(Fraction(float(x[0])) - exact[0]) / exact[0]) < 1e-12
    assert all(Fraction(float(lo)) <= e <= Fraction(float(hi)) for lo, hi, e in
               zip(found.lower, found.upper, exact, strict=True))


def test_a_kept_system_holds_one_copy_of_its_rows() -> None:
    """After the first map the system's rows are the map's (no diagonal entries) and
    the kept template carries no query's vectors."""
    P = _forward_chain(300)
    target = np.zeros(300, dtype=bool)
    target[-1] = True
    workspace = Workspace()
    kernels.reach_rewards(P, np.ones(300), target, workspace=workspace)
    system = next(iter(workspace.kernels.of(P).systems.values()))
    assert system.template is not None
    assert system.rows is system.template.rows
    assert system.template.known_lower.size == 0 and system.template.offset is None
    # The second query on the same system still gets the right numbers.
    twice = kernels.reach_rewards(P, np.full(300, 2.0), target, workspace=workspace)
    exact = _steps_exact(300)
    assert all(Fraction(float(lo)) <= 2 * e <= Fraction(float(hi)) for lo, hi, e in
               zip(twice.lower, twice.upper, exact, strict=True))


def test_retained_memory_per_state_after_a_large_solve() -> None:
    """Live memory kept by the workspace after ``R=? [ F target ]`` on 200,000 states: the
    rows once, the map's two leaving vectors, the substitution and the pre-pass graph
    -- about 130 bytes a state (it was about 200: rows twice, ``I - P_mm`` with its
    residue, a second copy of the substitution's indices, three map constants)."""
    n = 200_000
    P = _forward_chain(n)
    target = np.zeros(n, dtype=bool)
    target[-1] = True
    rewards = np.ones(n)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        workspace = Workspace()
        found = kernels.reach_rewards(P, rewards, target, workspace=workspace)
        value = float(found.value[0])
        del found
        kept = tracemalloc.get_traced_memory()[0] - before
        assert workspace.kernels.of(P).systems  # what is measured: the kept system
    finally:
        tracemalloc.stop()
    assert kept < 160 * n, f"{kept / n:.0f} bytes per state kept"
    # E[steps] from 0: 1 / (expected step length 1.75), up to the end effects.
    assert abs(value - (n - 1) / 1.75) < 2.0


def test_all_zero_reward_parts_take_no_memory() -> None:
    zero, ones = np.zeros(1 << 17), np.ones(1 << 17)
    rewards = RewardVectors("r", zero, ones)
    assert rewards.state.strides == (0,) and not rewards.state.flags.writeable
    assert np.array_equal(rewards.total, ones)
    signed = RewardVectors("s", np.full(1 << 17, -0.0), ones)  # -0.0 is kept as it is
    assert signed.state.strides == (8,)


def test_compact_state_table_keeps_every_value() -> None:
    states = np.array([[0, 200, -3], [1, 7, 0]], dtype=np.int64)
    P = sp.csr_matrix(np.eye(2))
    dtmc = DTMC(P, states, ("a", "b", "c"), np.array([0]), {}, ())
    narrow = dtmc.compact()
    assert narrow.states.dtype == np.int16 and np.array_equal(narrow.states, states)
    wide = DTMC(P, states * 2**40, ("a", "b", "c"), np.array([0]), {}, ())
    assert wide.compact() is wide


MODEL = """dtmc
module m
  x : [0..120] init 0;
  [] x < 120 -> 0.5 : (x'=x+1) + 0.5 : (x'=min(120, x+2));
  [] x = 120 -> true;
endmodule
"""


def test_expressions_over_a_narrow_table_do_not_overflow() -> None:
    """``x*x*x*1000`` overflows int8 (x <= 120 fits int8): atoms are evaluated on int64
    copies, so the answers equal those of the full table (``keep="states"`` keeps it)."""
    props = ('P=? [ F x*x*x*1000 > 1000000000 ]', 'filter(max, x*x*x*1000)',
             'P=? [ F x*x*x*1000 = 1728000000 ]')
    narrow = check_prism_file(MODEL, selectors=props, keep="answers")
    full = check_prism_file(MODEL, selectors=props, keep="states")
    assert narrow.dtmc.states.dtype == np.int8
    assert [r.value for r in narrow.results] == [r.value for r in full.results]
    assert narrow.results[0].value == pytest.approx(1.0)  # x reaches 120 surely
    assert narrow.results[1].value == 120**3 * 1000
    assert narrow.results[2].value == pytest.approx(1.0)  # 1728000000 = 1200**3: x = 120
