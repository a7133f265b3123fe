"""Properties of one model share one linear system (kernels.shared_system, Workspace.prepare).

``P=? [ F "success" ]``, ``R=? [ F "done" ]`` and the conditional ``R=? [ F "done" ||
F "success" ]`` of a mission are solved on the reward query's system, whose unknown
states are a superset of the others'. The oracle is independent of that construction:
each quantity in ``fractions.Fraction`` by Gauss-Jordan elimination on its own unknown
states (tests/checker/test_conditional_certified.py), the conditional one on the
conditioned chain. Probabilities are dyadic, so the float model is the rational one.
"""

from __future__ import annotations

import random
from fractions import Fraction

import numpy as np
import pytest

from tests.checker.chains import matrix
from tests.checker.test_conditional_certified import (
    Rows,
    _expected,
    _prism,
    _until,
    oracle,
)
from veribattery.checker import Workspace, kernels
from veribattery.checker.result import CheckResult
from veribattery.pipeline import check_prism_file

PROPS = ('P=? [ F "b" ];\nR{"r"}=? [ F "a" ];\nR{"r"}=? [ F "a" || F "b" ];\n'
         'P=? [ F "a" || F "b" ];\nP=? [ "c" U "b" ]')


def _mission_like(seed: int) -> tuple[Rows, list[Fraction], list[bool], list[bool]]:
    """Transient states 0..n-3 that all end in success (n-2) or failure (n-1), absorbing;
    cycles among them; some states surely succeed, some surely fail; success possible
    from state 0 (the first such chain of the seed's stream)."""
    rng = random.Random(seed)
    while True:
        chain = _draw(rng)
        if _until(chain[0], [True] * len(chain[0]), chain[3])[0] > 0:
            return chain


def _draw(rng: random.Random) -> tuple[Rows, list[Fraction], list[bool], list[bool]]:
    n = rng.randint(7, 11)
    success, failure = n - 2, n - 1
    rows: Rows = []
    for s in range(n - 2):
        # Forward to s+1 (or to the end), sometimes back, sometimes straight to an end.
        ahead = s + 1 if s + 1 < n - 2 else rng.choice((success, failure))
        targets = list(dict.fromkeys([ahead, rng.randrange(0, s + 1),
                                      rng.choice((success, failure, ahead))]))
        cuts = sorted(rng.sample(range(1, 16), len(targets) - 1))
        parts = [b - a for a, b in zip([0, *cuts], [*cuts, 16], strict=True)]
        rows.append({t: Fraction(p, 16) for t, p in zip(targets, parts, strict=True)})
    sure, doomed = rng.sample(range(1, n - 2), 2)
    rows[sure] = {success: Fraction(1)}
    rows[doomed] = {failure: Fraction(1)}
    rows += [{success: Fraction(1)}, {failure: Fraction(1)}]
    rewards = [Fraction(rng.randint(0, 4)) for _ in range(n - 2)] + [Fraction(0)] * 2
    done = [s >= n - 2 for s in range(n)]
    succeeded = [s == success for s in range(n)]
    return rows, rewards, done, succeeded


def _with_c(text: str, n: int) -> str:
    """The model text with a label "c": every state but state 1 (a ``c U b`` whose
    unknowns leave the reward system, which holds state 1: solved on its own)."""
    return text + 'label "c" = ' + "|".join(f"s={s}" for s in range(n) if s != 1) + ";\n"


def _contains(result: CheckResult, expected: Fraction) -> bool:
    assert result.lower is not None and result.upper is not None
    return Fraction(result.lower) <= expected <= Fraction(result.upper)


@pytest.mark.parametrize("seed", range(16))
def test_shared_solves_hold_the_rational_answers(seed: int, systems_built: list[int]) -> None:
    rows, rewards, done, succeeded = _mission_like(seed)
    n = len(rows)
    text = _with_c(_prism(rows, rewards, done, succeeded), n)
    results = check_prism_file(text, props_source=PROPS).results
    conditional = oracle(rows, rewards, done, succeeded, 0)
    c = [s != 1 for s in range(n)]
    expected = [_until(rows, [True] * n, succeeded)[0], _expected(rows, rewards, done)[0],
                conditional["R"], conditional["F"], _until(rows, c, succeeded)[0]]
    for result, value in zip(results, expected, strict=True):
        assert isinstance(value, Fraction)
        assert _contains(result, value), (result.property.text, result, value)
        assert result.precise
        assert float(result.value) == pytest.approx(float(value), rel=1e-12, abs=1e-15)


def test_the_until_is_solved_on_the_reward_system(systems_built: list[int]) -> None:
    rows, rewards, done, succeeded = _mission_like(3)
    text = _prism(rows, rewards, done, succeeded)
    props = 'P=? [ F "b" ];\nR{"r"}=? [ F "a" ];\nR{"r"}=? [ F "a" || F "b" ]'
    results = check_prism_file(text, props_source=props).results
    # One system (R's unknowns: the reachable transient states), built before P is checked.
    assert len(systems_built) == 1
    assert _contains(results[0], _until(rows, [True] * len(rows), succeeded)[0])


def test_sharing_gives_the_values_of_separate_checks() -> None:
    rows, rewards, done, succeeded = _mission_like(5)
    text = _with_c(_prism(rows, rewards, done, succeeded), len(rows))
    together = check_prism_file(text, props_source=PROPS).results
    alone = [check_prism_file(text, props_source=p).results[0] for p in PROPS.split(";\n")]
    for a, b in zip(together, alone, strict=True):
        assert float(a.value) == pytest.approx(float(b.value), rel=1e-12, abs=1e-15)


def test_no_superset_when_the_until_has_another_target_inside() -> None:
    # 0 -> 1 -> 2 (done), 1 -> 0; target {1}: R's unknowns {0, 1} hold the target.
    P = matrix({0: {1: 0.5, 2: 0.5}, 1: {0: 0.5, 2: 0.5}}, 3)
    done = np.array([False, False, True])
    workspace = Workspace()
    kernels.prepare_reach(P, done, workspace=workspace)
    target = np.array([False, True, False])
    found = kernels.until_probs(P, np.ones(3, dtype=bool), target, workspace=workspace)
    assert found.lower[0] <= 0.5 <= found.upper[0] and found.value[1] == 1.0
    maybe, allowed = kernels.until_unknowns(P, np.ones(3, dtype=bool), target,
                                            workspace=workspace)
    assert maybe.tolist() == [True, False, False] and not allowed[1]


def test_until_results_are_shared_with_the_condition() -> None:
    P = matrix({0: {1: 0.25, 2: 0.75}, 1: {0: 0.5, 3: 0.5}}, 4)
    everywhere = np.ones(4, dtype=bool)
    target = np.array([False, False, False, True])
    workspace = Workspace()
    first = kernels.until_probs(P, everywhere, target, workspace=workspace)
    assert kernels.until_probs(P, everywhere, target.copy(), workspace=workspace) is first
    # Only through the workspace: another computes its own.
    other = kernels.until_probs(P, everywhere, target, workspace=Workspace())
    assert other is not first and np.array_equal(other.value, first.value)
    # x0 = 1/4 x1, x1 = 1/2 x0 + 1/2 => x0 = 1/7
    assert first.lower[0] <= Fraction(1, 7) <= first.upper[0]
