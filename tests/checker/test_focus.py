"""Bounds certified at the initial states only (checker/focus.py).

When only a property's answer is kept (``keep_states=False``: ``check``, ``prism``, a
sweep point), the kernels bound the error at the initial state by ``w . d``: ``d`` the
enclosed defect of the approximate solution, ``w`` a certified upper bound of the initial
state's row of ``(I - B)^-1`` (one transposed solve per system, shared by every query on
it). The oracle is exact: each value, and each entry of that row, in ``fractions.Fraction``
by Gauss-Jordan elimination (tests/checker/test_conditional_certified.py). Probabilities
are dyadic, so the float model is the rational one. The focused certificate runs where the
quick one does (``QUICK_MIN_STATES`` unknowns and more): the tests lower that bound.
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
from veribattery.checker import focus, kernels, linsolve
from veribattery.pipeline import check_prism_file

PROPS = ('R{"r"}=? [ F "a" ];\nP=? [ F "t" ];\nP=? [ "c" U "t" ];\n'
         'R{"r"}=? [ F "a" || F "b" ];\nP=? [ F "b" ]')


@pytest.fixture
def focused(quick_systems: SpyAnswers) -> list[bool]:
    """``quick_systems``; per focused attempt, whether it answered."""
    return quick_systems(focus, "focused_bounds")


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
    answers = check_prism_file(text, props_source=PROPS, keep_states=False).results
    whole = check_prism_file(text, props_source=PROPS).results
    expected = _expected_answers(built, rewards, done, succeeded, t)
    assert_rational_answers(answers, expected)
    for answer, full in zip(answers, whole, strict=True):
        assert answer.value == full.value  # the same approximate solution
        assert answer.bounds is None and answer.values.size == 0
    assert focused and all(focused)  # every focused attempt answered


@pytest.mark.parametrize("seed", range(3))
def test_a_cyclic_system_is_certified_whole(seed: int, focused: list[bool]) -> None:
    # An SCC-wise solver has no transposed substitution: the whole vector is certified.
    chain = _forward_chain(seed, back=True)
    answers = check_prism_file(_text(*chain), props_source=PROPS, keep_states=False).results
    for answer, value in zip(answers, _expected_answers(*chain), strict=True):
        assert _contains(answer, value), (answer.property.text, answer, value)
        assert answer.precise
    assert not focused


def test_a_condition_is_computed_once(focused: list[bool],
                                      monkeypatch: pytest.MonkeyPatch) -> None:
    # P=? [ F "b" ] asked at the initial state alone, and the condition F "b" of the
    # conditional property needed in every state: one computation serves both.
    calls: list[int] = []
    original = kernels._until_probs

    def counting(*args):  # type: ignore[no-untyped-def]
        calls.append(1)
        return original(*args)

    monkeypatch.setattr(kernels, "_until_probs", counting)
    chain = _forward_chain(4)
    props = 'P=? [ F "b" ];\nR{"r"}=? [ F "a" || F "b" ]'
    answers = check_prism_file(_text(*chain), props_source=props, keep_states=False).results
    expected = _expected_answers(*chain)
    assert _contains(answers[0], expected[4]) and _contains(answers[1], expected[3])
    assert len(calls) == 1


@pytest.mark.parametrize("seed", range(8))
def test_certified_row_bounds_the_exact_row(seed: int) -> None:
    rows, rewards, done, succeeded, t = _forward_chain(seed)
    run = check_prism_file(_text(rows, rewards, done, succeeded, t),
                           props_source='R{"r"}=? [ F "a" ]')
    dtmc = run.dtmc
    P = dtmc.transitions
    named = dtmc.column("s")  # the chain's state of each DTMC state
    maybe = kernels.reach_unknowns(P, np.array([done[int(v)] for v in named]))
    system = kernels._system(P, maybe)
    zeros = np.zeros(P.shape[0])
    F = system.affine(zeros, zeros, np.zeros(int(maybe.sum())))
    states = [int(s) for s in F.states]
    k = states.index(int(dtmc.initial[0]))
    row = focus.certified_row(F, system.factorization.dual, k)
    assert row is not None and row.position == k
    exact = _exact_row(P, states, k)
    for weight, value in zip(row.weights.tolist(), exact, strict=True):
        assert Fraction(weight) >= value
        assert weight <= float(value) * (1 + 1e-12) + 1e-300  # and tight
        if value == 0:
            assert weight == 0  # a state the focus state does not reach keeps weight 0


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
    inverse = linsolve._triangular_inverse(A)
    assert isinstance(inverse, linsolve._Triangular)
    v = rng.random(n)
    B = dense / leave[:, None]
    expected = np.linalg.solve((np.eye(n) - B).T, v)  # w^T (I - B) = v^T
    np.testing.assert_allclose(inverse.dual(v.copy()), expected, rtol=1e-12)
    # The forward solve is unchanged by making the transposed one.
    b = rng.random(n)
    np.testing.assert_allclose(inverse(b.copy()), np.linalg.solve(A.toarray(), b), rtol=1e-12)


def test_no_certificate_when_the_row_fails(monkeypatch: pytest.MonkeyPatch) -> None:
    # A transposed solver that returns a poor row: the test fails, nothing is claimed.
    rows, rewards, done, succeeded, t = _forward_chain(2)
    run = check_prism_file(_text(rows, rewards, done, succeeded, t),
                           props_source='R{"r"}=? [ F "a" ]')
    P = run.dtmc.transitions
    maybe = kernels.reach_unknowns(P, np.array([done[int(v)] for v in run.dtmc.column("s")]))
    system = kernels._system(P, maybe)
    zeros = np.zeros(P.shape[0])
    F = system.affine(zeros, zeros, None)
    assert focus.certified_row(F, lambda v: np.zeros_like(v), 0) is None
