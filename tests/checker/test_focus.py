"""Bounds certified at the initial states only (checker/certify/focus.py).

When only a property's answer is kept (``keep="answers"``: ``check``, ``prism``, a
sweep point), the kernels certify the initial state's row of ``(I - B)^-1`` from both
sides (one transposed solve per system, shared by every query on it) and enclose each
answer as that row times the enclosed right-hand side; a pinned copy of a system, for
which only the upper bound holds, bounds the error of an approximate solution by
``w . d`` (``d`` its enclosed defect). The oracle is exact: each value, and each entry
of that row, in ``fractions.Fraction`` by Gauss-Jordan elimination
(tests/checker/test_conditional_certified.py), of the model as built (``_as_built``), with
non-dyadic probabilities (``_thirds``) where the float solution must not be exact. The
focused certificate runs where the quick one does (``QUICK_MIN_STATES`` unknowns and
more): the tests lower that bound.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker.conftest import SpyAnswers
from tests.checker.test_conditional_certified import Rows, _expected, _solve, _until, oracle
from tests.checker.test_pinned_systems import (
    _contains,
    _forward_chain,
    _text,
    acyclic_rows,
    assert_rational_answers,
)
from veribattery.checker import certify, kernels
from veribattery.checker.certify import focus
from veribattery.checker.certify.bounds import required_precision
from veribattery.checker.certify.rounding import TERM_FLOOR, error_coefficient
from veribattery.checker.kernels import systems, until
from veribattery.checker.linalg import triangular
from veribattery.pipeline import check_prism_file

PROPS = ('R{"r"}=? [ F "a" ];\nP=? [ F "t" ];\nP=? [ "c" U "t" ];\n'
         'R{"r"}=? [ F "a" || F "b" ];\nP=? [ F "b" ]')


@pytest.fixture
def focused(quick_systems: SpyAnswers) -> list[bool]:
    """``quick_systems``; per focused attempt (from the rows alone, or from an
    approximate solution's defect), whether it answered."""
    answered = quick_systems(focus, "answered_bounds")
    by_defect = quick_systems(focus, "focused_bounds")
    return answered + by_defect if by_defect else answered


def _expected_answers(rows: Rows, rewards: list[Fraction], done: list[bool],
                      succeeded: list[bool], t: list[bool]) -> list[Fraction | float]:
    n = len(rows)
    c = [s != 2 for s in range(n)]
    return [_expected(rows, rewards, done)[0], _until(rows, [True] * n, t)[0],
            _until(rows, c, t)[0], oracle(rows, rewards, done, succeeded, 0)["R"],
            _until(rows, [True] * n, succeeded)[0]]


def _thirds(rows: Rows) -> Rows:
    """*rows* with the first two probabilities of each row moved by 1/48 each way: not
    dyadic, so the float solution is not exact and the bounds have work to do."""
    moved: Rows = []
    for row in rows:
        entries = list(row.items())
        if len(entries) >= 2:
            (t0, p0), (t1, p1) = entries[:2]
            entries[:2] = [(t0, p0 - Fraction(1, 48)), (t1, p1 + Fraction(1, 48))]
        moved.append(dict(entries))
    return moved


def _as_built(text: str, n: int) -> tuple[Rows, int]:
    """The model as built, in rationals (each float entry exactly, the self-loop ``1 -``
    the others, as the checker reads it), in the chain's own numbering of its *n* states
    (those not reached from the initial one absorbing); and the initial state."""
    dtmc = check_prism_file(text, props_source="P=? [ F true ]").dtmc
    P, named = dtmc.transitions, [int(v) for v in dtmc.column("s")]
    rows: Rows = [{s: Fraction(1)} for s in range(n)]
    for s, chain_state in enumerate(named):
        begin, end = P.indptr[s], P.indptr[s + 1]
        row = {named[int(c)]: Fraction(float(v)) for c, v in
               zip(P.indices[begin:end], P.data[begin:end], strict=True) if int(c) != s}
        stay = 1 - sum(row.values(), Fraction(0))
        rows[chain_state] = {**row, chain_state: stay} if stay else row
    return rows, named[int(dtmc.initial[0])]


@pytest.mark.parametrize("seed", range(12))
def test_answers_certified_at_the_initial_state_hold_the_rational_answer(
        seed: int, focused: list[bool]) -> None:
    rows, rewards, done, succeeded, t = _forward_chain(seed)
    text = _text(_thirds(rows), rewards, done, succeeded, t)
    built, initial = _as_built(text, len(rows))
    assert initial == 0
    answers = check_prism_file(text, props_source=PROPS, keep="answers").results
    whole = check_prism_file(text, props_source=PROPS).results
    expected = _expected_answers(built, rewards, done, succeeded, t)
    assert_rational_answers(answers, expected)
    for answer, full in zip(answers, whole, strict=True):
        assert answer.value == pytest.approx(full.value, rel=1e-13)
        assert answer.bounds is None and answer.values.size == 0
    assert focused and all(focused)  # every focused attempt answered


@pytest.mark.parametrize("seed", range(3))
def test_a_cyclic_system_is_certified_whole(seed: int, focused: list[bool]) -> None:
    # An SCC-wise solver has no transposed substitution: the whole vector is certified.
    chain = _forward_chain(seed, back=True)
    answers = check_prism_file(_text(*chain), props_source=PROPS, keep="answers").results
    for answer, value in zip(answers, _expected_answers(*chain), strict=True):
        assert _contains(answer, value), (answer.property.text, answer, value)
        assert answer.precise
    assert not focused


def test_a_condition_is_computed_once(focused: list[bool],
                                      monkeypatch: pytest.MonkeyPatch) -> None:
    # P=? [ F "b" ] asked at the initial state alone, and the condition F "b" of the
    # conditional property needed in every state: one computation serves both.
    calls: list[int] = []
    original = until._until_probs

    def counting(*args):  # type: ignore[no-untyped-def]
        calls.append(1)
        return original(*args)

    monkeypatch.setattr(until, "_until_probs", counting)
    chain = _forward_chain(4)
    props = 'P=? [ F "b" ];\nR{"r"}=? [ F "a" || F "b" ]'
    answers = check_prism_file(_text(*chain), props_source=props, keep="answers").results
    expected = _expected_answers(*chain)
    assert _contains(answers[0], expected[4]) and _contains(answers[1], expected[3])
    assert len(calls) == 1


@pytest.mark.parametrize("seed", range(12))
def test_certified_row_bounds_the_exact_row(seed: int) -> None:
    # Non-dyadic (_thirds), so the float row is not the exact one.
    rows, rewards, done, succeeded, t = _forward_chain(seed)
    run = check_prism_file(_text(_thirds(rows), rewards, done, succeeded, t),
                           props_source='R{"r"}=? [ F "a" ]')
    dtmc = run.dtmc
    P = dtmc.transitions
    named = dtmc.column("s")  # the chain's state of each DTMC state
    maybe = kernels.reach_unknowns(P, np.array([done[int(v)] for v in named]),
                                   workspace=run.workspace)
    system = systems._system(P, maybe, workspace=run.workspace)
    zeros = np.zeros(P.shape[0])
    F = system.affine(zeros, zeros, np.zeros(int(maybe.sum())))
    states = [int(s) for s in F.states]
    k = states.index(int(dtmc.initial[0]))
    row = focus.certified_row(F, system.factorization.dual, k)
    assert row is not None and row.position == k and row.lower is not None
    exact = _exact_row(P, states, k)
    for low, high, value in zip(row.lower.tolist(), row.upper.tolist(), exact, strict=True):
        assert Fraction(low) <= value <= Fraction(high)
        assert high - low <= float(value) * 1e-12 + 1e-300  # and tight
        if value == 0:
            assert high == 0  # a state the focus state does not reach keeps weight 0


@pytest.mark.parametrize("seed", range(6))
def test_sum_bounds_hold_the_exact_sum(seed: int) -> None:
    # Products of mixed signs and magnitudes with heavy cancellation: the exact sum of
    # the exact products (in rationals) lies between the bounds, and they are tight.
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 3000))
    a = rng.random(n) * 10.0 ** rng.integers(-12, 12, size=n)
    b = rng.standard_normal(n)
    products = a * b
    lower, upper = focus._sum_bounds(products)
    exact = sum((Fraction(float(x)) * Fraction(float(y)) for x, y in zip(a, b, strict=True)),
                Fraction(0))
    assert Fraction(lower) <= exact <= Fraction(upper)
    magnitude = float(np.sum(np.abs(products)))
    assert upper - lower <= 1e-13 * magnitude


def test_sum_bounds_cover_the_products_rounding() -> None:
    # fl(3 * fl(1/3)) is 1 but the exact product is not; against exact -1s the float sum
    # cancels to 0 while the exact one does not: only the error bound holds it.
    third = 1.0 / 3.0
    products = np.tile([third * 3.0, -1.0], 1 << 11)
    assert float(np.sum(products)) == 0.0
    exact = (Fraction(third) * 3 - 1) * (1 << 11)
    assert exact != 0
    lower, upper = focus._sum_bounds(products)
    assert Fraction(lower) <= exact <= Fraction(upper)


def _reward_map(seed: int, *, non_dyadic: bool) -> certify.AffineMap:
    """The fixed-point map of ``R{"r"}=? [ F "a" ]`` on a random forward chain."""
    rows, rewards, done, succeeded, t = _forward_chain(seed)
    run = check_prism_file(_text(_thirds(rows) if non_dyadic else rows, rewards, done,
                                 succeeded, t), props_source='R{"r"}=? [ F "a" ]')
    P = run.dtmc.transitions
    maybe = kernels.reach_unknowns(P, np.array([done[int(v)] for v in run.dtmc.column("s")]),
                                   workspace=run.workspace)
    zeros = np.zeros(P.shape[0])
    return systems._system(P, maybe, workspace=run.workspace).affine(zeros, zeros, None)


@pytest.mark.parametrize("seed", range(6))
def test_radius_covers_a_poor_approximation(seed: int) -> None:
    # The one-sided radius (a pinned query's bound) from an approximation off by ~1e-7:
    # the bounds at the initial state still hold the exact rational answer, and are
    # at least as wide as the error (no ulp-sized interval could hold it).
    rows, rewards, done, succeeded, t = _forward_chain(seed)
    text = _text(_thirds(rows), rewards, done, succeeded, t)
    built, initial = _as_built(text, len(rows))
    exact = _expected(built, rewards, done)[initial]
    run = check_prism_file(text, props_source='R{"r"}=? [ F "a" ]')
    P, dtmc = run.dtmc.transitions, run.dtmc
    maybe = kernels.reach_unknowns(P, np.array([done[int(v)] for v in dtmc.column("s")]),
                                   workspace=run.workspace)
    system = systems._system(P, maybe, workspace=run.workspace)
    zeros = np.zeros(P.shape[0])
    F = system.affine(zeros, zeros, np.asarray(dtmc.rewards[0].total[maybe], dtype=float))
    k = int(np.searchsorted(F.states, dtmc.initial[0]))
    row = focus.certified_row(F, system.factorization.dual, k)
    assert row is not None
    x = run.results[0].values[maybe] + 1e-7  # every state off by 1e-7
    with required_precision(1e-3, 1e-3):  # (an interval this wide is not precise by default)
        found = focus.focused_bounds(F, x, [row.above_only()], np.full((), 0.0),
                                     np.full((), np.inf))
    assert found is not None
    assert Fraction(float(found.lower[k])) <= exact <= Fraction(float(found.upper[k]))
    assert found.upper[k] - found.lower[k] >= 1e-7


def test_image_terms_count_the_nonzero_products() -> None:
    # The rounding bound of (B^T w)_j counts the nonzero terms of column j: a weighted
    # sum of the pattern (the probabilities themselves) would undercount them.
    F = _reward_map(5, non_dyadic=True)
    rng = np.random.default_rng(5)
    nonzero = rng.random(F.states.size) < 0.7
    terms = focus._ImageTerms.of(F, nonzero, 0)
    dense = F.rows.toarray()[:, F.states] != 0  # stored entries P'_ij, unknown columns j
    counts = (dense & nonzero[:, None]).sum(axis=0).astype(float)
    counts[0] += 1.0  # the focus position's 1
    assert counts.max() > 1  # several terms in some column
    np.testing.assert_array_equal(terms.coefficient, error_coefficient(counts))
    np.testing.assert_array_equal(terms.underflow, counts * TERM_FLOOR)


def _exact_row(P: sp.csr_matrix, states: list[int], k: int) -> list[Fraction]:
    """Row *k* of ``(I - B)^-1`` on *states* in rationals: ``w = e_k + B^T w`` with
    ``B_ij = P_ij / s_i`` off the diagonal, ``s_i`` the row's off-diagonal sum."""
    position = {s: i for i, s in enumerate(states)}
    transposed: Rows = [{} for _ in states]
    for i, s in enumerate(states):
        entries = {int(c): Fraction(float(v)) for c, v in
                   zip(P.indices[P.indptr[s]:P.indptr[s + 1]],
                       P.data[P.indptr[s]:P.indptr[s + 1]], strict=True) if int(c) != s}
        leave = sum(entries.values(), Fraction(0))
        for c, p in entries.items():
            if c in position:
                transposed[position[c]][i] = p / leave
    values = _solve(transposed, list(range(len(states))), {k: Fraction(1)},
                    [Fraction(0)] * len(states))
    return [values[i] for i in range(len(states))]


def test_dual_solve_is_the_transposed_system() -> None:
    rng = np.random.default_rng(7)
    n = 40
    dense = acyclic_rows(rng, n)
    leave = rng.integers(4, 16, size=n) / 16  # the diagonal D (leaving probabilities)
    A = sp.csr_matrix(np.diag(leave) - dense)
    inverse = triangular._triangular_inverse(A)
    assert isinstance(inverse, triangular._Triangular)
    v = rng.random(n)
    B = dense / leave[:, None]
    expected = np.linalg.solve((np.eye(n) - B).T, v)  # w^T (I - B) = v^T
    np.testing.assert_allclose(inverse.dual(v.copy()), expected, rtol=1e-12)
    # The forward solve is unchanged by making the transposed one.
    b = rng.random(n)
    np.testing.assert_allclose(inverse(b.copy()), np.linalg.solve(A.toarray(), b), rtol=1e-12)


def test_no_certificate_when_the_row_fails(monkeypatch: pytest.MonkeyPatch) -> None:
    # A transposed solver that returns a poor row: the test fails, nothing is claimed.
    F = _reward_map(2, non_dyadic=False)
    assert focus.certified_row(F, lambda v: np.zeros_like(v), 0) is None
