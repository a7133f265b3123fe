"""Long-run operators with ``--exact``: ``S=? [phi]``, ``S~p``, ``R=? [S]`` and ``R=? [C]``.

They crashed with a RecursionError (found by a differential run on Storm's test models).
Checked against the chain of ``test_pctl_language`` solved by hand, and against an
oracle over Fractions on random chains that computes each BSCC's stationary
distribution by solving ``pi (P - I) = 0, sum pi = 1`` (not the renewal theorem the
checker uses), and against the float checker's certified intervals.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from fractions import Fraction

import pytest

from tests.checker.test_exact import (
    chain_text,
    exact_run,
    fraction_solve,
    oracle_reach,
    random_chain,
)
from tests.checker.test_pctl_language import MODEL
from veribattery.pipeline import check_prism_file

HAND = [
    # (test_pctl_language's chain: pi(2,3,4) = (1/8, 1/2, 3/8), reached w.p. 2/3)
    ("S=? [ s=3 ]", Fraction(1, 3)),
    ("S=? [ s=2 ]", Fraction(1, 12)),
    ("S=? [ s=4 ]", Fraction(1, 4)),
    ("S=? [ s=1 ]", Fraction(1, 3)),
    ("S=? [ true ]", Fraction(1)),
    ('R{"r"}=? [ S ]', Fraction(2, 3)),
    ('filter(state, R{"r"}=? [ C ], s=1)', Fraction(0)),
    ("2 * S=? [ s=3 ] + 1", Fraction(5, 3)),
    ('filter(state, S=? [ s=3 ], s=4)', Fraction(1, 2)),
]


@pytest.mark.parametrize(("text", "expected"), HAND, ids=[case[0] for case in HAND])
def test_hand_solved_values(text: str, expected: Fraction) -> None:
    (result,) = exact_run(MODEL, text)
    assert result.exact == expected


def test_bounds_at_the_value_are_decided_exactly() -> None:
    run = check_prism_file(MODEL, selectors=("S>=1/3 [ s=3 ]", "S>1/3 [ s=3 ]",
                                             'R{"r"}<=2/3 [ S ]', 'R{"r"}<2/3 [ S ]'),
                           exact=True)
    assert [r.value for r in run.results] == [True, False, True, False]


def test_total_reward_is_infinite_where_a_paying_bscc_is_reached() -> None:
    (total,) = exact_run(MODEL, 'R{"r"}=? [ C ]')
    assert math.isinf(total.value) and total.exact is None


def _reachable(rows: Sequence[dict[int, Fraction]], start: int) -> set[int]:
    seen, stack = {start}, [start]
    while stack:
        for t in rows[stack.pop()]:
            if t not in seen:
                seen.add(t)
                stack.append(t)
    return seen


def _bsccs(rows: Sequence[dict[int, Fraction]]) -> list[list[int]]:
    found: list[list[int]] = []
    for s in range(len(rows)):
        ahead = _reachable(rows, s)
        if all(s in _reachable(rows, t) for t in ahead) and s == min(ahead):
            found.append(sorted(ahead))
    return found


def _stationary(rows: Sequence[dict[int, Fraction]], states: list[int]) -> list[Fraction]:
    """pi (P - I) = 0 on *states* with its last equation replaced by sum pi = 1."""
    k = len(states)
    matrix = [[rows[states[j]].get(states[i], Fraction(0)) - (i == j) for j in range(k)]
              for i in range(k)]
    matrix[-1] = [Fraction(1)] * k
    return fraction_solve(matrix, [Fraction(0)] * (k - 1) + [Fraction(1)])


def oracle_long_run(rows: Sequence[dict[int, Fraction]], weight: list[Fraction]) -> Fraction:
    """The long-run average of *weight* from state 0."""
    total = Fraction(0)
    for states in _bsccs(rows):
        pi = _stationary(rows, states)
        average = sum((p * weight[s] for p, s in zip(pi, states, strict=True)), Fraction(0))
        total += oracle_reach(rows, set(states))[0] * average
    return total


def clustered_chain(seed: int) -> list[dict[int, Fraction]]:
    """States 0-2 transient (each may also stay); 3-5 and 6-8 two closed classes, each
    a cycle (periodic unless a random extra edge breaks the period) plus random edges."""
    rng = random.Random(seed)
    rows: list[dict[int, Fraction]] = []
    for s in range(9):
        if s < 3:
            targets = {s, *rng.sample(range(9), 2), rng.choice(range(3, 9))}
        else:
            low = 3 if s < 6 else 6
            targets = {low + (s - low + 1) % 3, *rng.sample(range(low, low + 3), rng.randint(0, 2))}
        weights = {t: rng.randint(1, 9) for t in targets}
        total = sum(weights.values())
        rows.append({t: Fraction(w, total) for t, w in weights.items()})
    return rows


@pytest.mark.parametrize("seed", range(24))
def test_random_chains_match_the_stationary_oracle(seed: int) -> None:
    rows = random_chain(seed, 9) if seed < 12 else clustered_chain(seed)
    text = chain_text(rows)  # (reward: 1/2 everywhere, 3 more in s=1)
    reward = [Fraction(1, 2) + (3 if s == 1 else 0) for s in range(len(rows))]
    in_low = [Fraction(int(s <= 3)) for s in range(len(rows))]
    steady, average = exact_run(text, "S=? [ s<=3 ]", "R=? [ S ]")
    assert steady.exact == oracle_long_run(rows, in_low)
    assert average.exact == oracle_long_run(rows, reward)
    floats = check_prism_file(text, selectors=("S=? [ s<=3 ]", "R=? [ S ]")).results
    for exact, found in zip((steady, average), floats, strict=True):
        assert found.lower is not None and found.upper is not None
        assert found.lower <= exact.exact <= found.upper
