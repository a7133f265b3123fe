"""An until whose target states lie inside a kept system is solved on it, those rows pinned.

The mission's recharge-cap probability ``P=? [ F rc=RC_MAX ]`` has its target states
inside ``R=? [ F "done" ]``'s system: ``until._pinned_until`` solves it there with
the target (and other known) rows replaced by identity rows (``triangular._Triangular.
pinned``, ``certify.PinnedMap``) instead of building a second system. The oracle is
independent of that construction: each value in ``fractions.Fraction`` by Gauss-Jordan
elimination on its own unknown states (tests/checker/test_conditional_certified.py).
Probabilities are dyadic, so the float model is the rational one. The quick certificate
(the only way the pinned system is solved) runs on systems of ``QUICK_MIN_STATES``
unknowns and more: the tests lower that bound to reach it on small chains.
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker.conftest import SpyAnswers
from tests.checker.test_conditional_certified import Rows, _expected, _prism, _until
from veribattery.checker import certify
from veribattery.checker.certify import affine
from veribattery.checker.kernels import until
from veribattery.checker.linalg import triangular
from veribattery.checker.result import CheckResult
from veribattery.pipeline import check_prism_file

PROPS = 'R{"r"}=? [ F "a" ];\nP=? [ F "t" ];\nP=? [ "c" U "t" ]'


def _forward_chain(seed: int, *, back: bool = False
                   ) -> tuple[Rows, list[Fraction], list[bool], list[bool], list[bool]]:
    """Transient states 0..n-3 moving forward (with *back*, also 1 -> 0 -> 1) to
    success (n-2) or failure (n-1), absorbing; "t" a few transient states (inside the
    reward system), reached with a probability strictly between 0 and 1 from state 0."""
    rng = random.Random(seed)
    while True:
        n = rng.randint(8, 13)
        success, failure = n - 2, n - 1
        rows: Rows = []
        for s in range(n - 2):
            later = [t for t in range(s + 1, n)]
            targets = list(dict.fromkeys(rng.sample(later, min(len(later), 3))))
            if back and s == 0:  # 0 -> 1 -> 0: a cycle
                targets = [1, *(t for t in targets if t != 1)][:3]
            elif back and s == 1:
                targets = [0, *targets[:2]]
            cuts = sorted(rng.sample(range(1, 16), len(targets) - 1))
            parts = [b - a for a, b in zip([0, *cuts], [*cuts, 16], strict=True)]
            rows.append({t: Fraction(p, 16) for t, p in zip(targets, parts, strict=True)})
        rows += [{success: Fraction(1)}, {failure: Fraction(1)}]
        rewards = [Fraction(rng.randint(0, 4)) for _ in range(n - 2)] + [Fraction(0)] * 2
        done = [s >= n - 2 for s in range(n)]
        t = [s in rng.sample(range(1, n - 2), 2) for s in range(n)]
        chance = _until(rows, [True] * n, t)[0]
        if 0 < chance < 1:
            return rows, rewards, done, [s == success for s in range(n)], t


def _text(rows: Rows, rewards: list[Fraction], done: list[bool], succeeded: list[bool],
          t: list[bool]) -> str:
    n = len(rows)
    labels = {"t": t, "c": [s != 2 for s in range(n)]}
    extra = "".join(f'label "{name}" = ' + "|".join(f"s={s}" for s in range(n) if mask[s])
                    + ";\n" for name, mask in labels.items())
    return _prism(rows, rewards, done, succeeded) + extra


def _contains(result: CheckResult, expected: Fraction | float) -> bool:
    assert result.lower is not None and result.upper is not None
    return Fraction(result.lower) <= expected <= Fraction(result.upper)


def assert_rational_answers(results: Sequence[CheckResult],
                            expected: Sequence[Fraction | float]) -> None:
    """Each result's interval holds its rational answer, is precise, and its value is the
    answer to 1e-12."""
    for result, value in zip(results, expected, strict=True):
        assert _contains(result, value), (result.property.text, result, value)
        assert result.precise
        assert float(result.value) == pytest.approx(float(value), rel=1e-12, abs=1e-15)


@pytest.fixture
def quick_everywhere(quick_systems: SpyAnswers) -> list[bool]:
    """:func:`quick_systems`; per ``_pinned_until`` call, whether it answered."""
    return quick_systems(until, "_pinned_until")


@pytest.mark.parametrize("seed", range(12))
def test_pinned_until_holds_the_rational_answer(seed: int, quick_everywhere: list[bool],
                                                systems_built: list[int]) -> None:
    rows, rewards, done, succeeded, t = _forward_chain(seed)
    n = len(rows)
    results = check_prism_file(_text(rows, rewards, done, succeeded, t),
                               props_source=PROPS).results
    c = [s != 2 for s in range(n)]
    expected = [_expected(rows, rewards, done)[0], _until(rows, [True] * n, t)[0],
                _until(rows, c, t)[0]]
    assert all(isinstance(value, Fraction) for value in expected)
    assert_rational_answers(results, expected)
    # The untils were answered on the reward system, the only one built (``c U t``
    # may have nothing to solve).
    assert quick_everywhere and all(quick_everywhere)
    assert len(systems_built) == 1


@pytest.mark.parametrize("seed", range(4))
def test_a_cyclic_system_is_not_pinned(seed: int, quick_everywhere: list[bool],
                                       systems_built: list[int]) -> None:
    rows, rewards, done, succeeded, t = _forward_chain(seed, back=True)
    n = len(rows)
    text = _text(rows, rewards, done, succeeded, t)
    results = check_prism_file(text, props_source='R{"r"}=? [ F "a" ];\nP=? [ F "t" ]').results
    expected = _until(rows, [True] * n, t)[0]
    assert _contains(results[1], expected)
    assert float(results[1].value) == pytest.approx(float(expected), rel=1e-12, abs=1e-15)
    assert True not in quick_everywhere  # an SCC-wise solver has no pinned form
    assert len(systems_built) == 2


def acyclic_rows(rng: np.random.Generator, n: int) -> np.ndarray:
    """A dense substochastic matrix whose graph is acyclic, in a shuffled numbering (each
    state's successors precede it before the shuffle), entries in 16ths."""
    dense = np.zeros((n, n))
    for i in range(1, n):
        successors = rng.choice(i, size=min(i, 3), replace=False)
        dense[i, successors] = rng.integers(1, 5, size=successors.size) / 16
    shuffle = rng.permutation(n)
    return dense[np.ix_(shuffle, shuffle)]


def test_pinned_substitution_solves_the_pinned_system() -> None:
    rng = np.random.default_rng(5)
    n = 40
    dense = acyclic_rows(rng, n)
    A = sp.csr_matrix(np.eye(n) - dense)
    inverse = triangular._triangular_inverse(A)
    assert isinstance(inverse, triangular._Triangular)
    pinned = rng.random(n) < 0.3
    b = rng.random(n)
    system = np.where(pinned[:, None], np.eye(n), np.eye(n) - dense)
    x = inverse.pinned(pinned)(b)
    np.testing.assert_allclose(x, np.linalg.solve(system, b), rtol=1e-13)
    assert np.array_equal(x[pinned], b[pinned])
    # The unpinned substitution is unchanged by making a pinned one.
    np.testing.assert_allclose(inverse(b), np.linalg.solve(np.eye(n) - dense, b), rtol=1e-13)


def test_pinned_map_fixes_its_states() -> None:
    rows = sp.csr_matrix(np.array([[0.0, 0.5, 0.25, 0.25], [0.5, 0.0, 0.0, 0.5],
                                   [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]]))
    states = np.array([0, 1, 2])
    known = np.array([0.0, 0.0, 0.0, 1.0])
    F = certify.AffineMap.of(rows[states], states, known, known, None)
    G = certify.PinnedMap.around(F, np.array([2]), np.array([0.75]))
    x = np.array([0.5, 0.6, 0.1])
    low, high = G.images(x, x)
    assert low[2] == high[2] == 0.75 == G.lower(x)[2] == G.upper(x)[2]
    plain_low, plain_high = F.images(x, x)
    assert np.array_equal(low[:2], plain_low[:2]) and np.array_equal(high[:2], plain_high[:2])


@pytest.mark.parametrize("k", [1, 2, 3, 7, 1000, 2**22 - 1, 2**22, 2**40 + 3])
def test_error_coefficient_is_an_upper_bound(k: int) -> None:
    exact = 4 * Fraction(1, 2**53) * k * (1 + Fraction(1, 2**30))
    found = certify.error_coefficient(np.array([float(k)]))[0]
    assert Fraction(found) >= exact
    if k < 2**22:  # exact there: no rounding up needed
        assert Fraction(found) == exact
    half = certify.error_coefficient(np.array([k + 0.5]))[0]
    assert Fraction(half) >= 4 * Fraction(1, 2**53) * (k + Fraction(1, 2)) * (
        1 + Fraction(1, 2**30))


def test_kept_constants_give_the_same_images(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(2)
    n = 30
    dense = rng.random((n, n + 2)) * (rng.random((n, n + 2)) < 0.2)
    dense /= dense.sum(axis=1, keepdims=True) + 1.0
    rows = sp.csr_matrix(dense)
    states = np.arange(n)
    known = np.concatenate([np.zeros(n), [1.0, 0.0]])
    offset = rng.random(n)
    kept = certify.AffineMap.of(rows, states, known, known, offset)
    monkeypatch.setattr(affine, "KEEP_CONSTANTS_BELOW", 0)
    derived = certify.AffineMap.of(rows, states, known, known, offset)
    assert kept.constants is not None and derived.constants is None
    x = rng.random(n)
    for a, b in zip(kept.images(x, x), derived.images(x, x), strict=True):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("seed", range(10))
def test_untils_share_one_system_on_their_union(seed: int, quick_everywhere: list[bool],
                                                systems_built: list[int]) -> None:
    # No reward query: Workspace.prepare builds one system on the union of the two untils'
    # unknowns (kernels.prepare_untils); "success" is solved on it as a superset, "t"
    # with its target rows inside it pinned.
    rows, rewards, done, succeeded, t = _forward_chain(seed)
    n = len(rows)
    results = check_prism_file(_text(rows, rewards, done, succeeded, t),
                               props_source='P=? [ F "b" ];\nP=? [ F "t" ]').results
    assert_rational_answers(results, [_until(rows, [True] * n, succeeded)[0],
                                      _until(rows, [True] * n, t)[0]])
    assert len(systems_built) == 1


def test_a_cyclic_union_is_not_kept(quick_everywhere: list[bool],
                                    systems_built: list[int]) -> None:
    rows, rewards, done, succeeded, t = _forward_chain(1, back=True)
    n = len(rows)
    results = check_prism_file(_text(rows, rewards, done, succeeded, t),
                               props_source='P=? [ F "b" ];\nP=? [ F "t" ]').results
    for result, value in zip(results, [_until(rows, [True] * n, succeeded)[0],
                                       _until(rows, [True] * n, t)[0]], strict=True):
        assert _contains(result, value)
    # The union was built, found cyclic and dropped; each until then built its own.
    assert len(systems_built) == 3
