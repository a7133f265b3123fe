"""Certified and exact conditional results (Storm's ``||``).

The float checker's interval must contain the exact rational answer and meet the 1e-9
default; ``--exact`` must equal it. The oracle is independent of the checker's ratio
construction: it builds the conditioned chain (Doob's h-transform, two copies) in
``fractions.Fraction`` and solves plain reachability and expected rewards on it by
Gaussian elimination. Models use dyadic probabilities, so the float model as built is
the rational one.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path

import pytest

from tests.checker.test_conditional import CHAIN, small_mission_storm_exact
from veribattery.checker.exact import ExactCheckResult
from veribattery.checker.result import CheckResult
from veribattery.errors import CheckError
from veribattery.pipeline import check_prism_file

Rows = list[dict[int, Fraction]]
INF = math.inf


# ---------------------------------------------------------------------------
# Oracle: the conditioned chain in rationals
# ---------------------------------------------------------------------------


def _reach_set(rows: Rows, through: Sequence[bool], seeds: Sequence[bool]) -> list[bool]:
    """States with a path to *seeds* whose states before the last lie in *through*."""
    found = list(seeds)
    changed = True
    while changed:
        changed = False
        for s, row in enumerate(rows):
            if not found[s] and through[s] and any(found[t] for t in row):
                found[s] = changed = True
    return found


def _solve(rows: Rows, unknown: list[int], constant: dict[int, Fraction],
           known: Sequence[Fraction]) -> dict[int, Fraction]:
    """``v = c + P v`` on *unknown* (known values elsewhere), by Gauss-Jordan elimination."""
    index = {s: i for i, s in enumerate(unknown)}
    m = len(unknown)
    A = [[Fraction(int(i == j)) for j in range(m)] + [constant.get(s, Fraction(0))]
         for i, s in enumerate(unknown)]
    for i, s in enumerate(unknown):
        for t, p in rows[s].items():
            if t in index:
                A[i][index[t]] -= p
            else:
                A[i][m] += p * known[t]
    for col in range(m):
        pivot = next(r for r in range(col, m) if A[r][col] != 0)
        A[col], A[pivot] = A[pivot], A[col]
        A[col] = [v / A[col][col] for v in A[col]]
        for r in range(m):
            if r != col and A[r][col] != 0:
                A[r] = [a - A[r][col] * b for a, b in zip(A[r], A[col], strict=True)]
    return {s: A[i][m] for i, s in enumerate(unknown)}


def _until(rows: Rows, remain: Sequence[bool], target: Sequence[bool]) -> list[Fraction]:
    n = len(rows)
    can = _reach_set(rows, [r and not t for r, t in zip(remain, target, strict=True)], target)
    known = [Fraction(int(t)) for t in target]
    unknown = [s for s in range(n) if can[s] and not target[s]]
    values = _solve(rows, unknown, {}, known)
    return [values.get(s, known[s]) for s in range(n)]


def _conditioned(rows: Rows, b: Sequence[bool]) -> tuple[Rows, list[int], list[int]]:
    """The conditioned chain: (rows, origin of each product state, start of each state)."""
    n = len(rows)
    x = _until(rows, [True] * n, b)
    after = _reach_set([{} for _ in rows], [False] * n, b)  # b itself, then forward closure
    frontier = [s for s in range(n) if after[s]]
    while frontier:
        s = frontier.pop()
        for t in rows[s]:
            if not after[t]:
                after[t] = True
                frontier.append(t)
    before = [x[s] > 0 and not b[s] for s in range(n)]
    origin = [s for s in range(n) if before[s]] + [s for s in range(n) if after[s]]
    copy0 = {s: i for i, s in enumerate(origin) if before[s] and i < sum(before)}
    copy1 = {s: i + sum(before) for i, s in enumerate(s for s in range(n) if after[s])}
    product: Rows = []
    for s in (s for s in range(n) if before[s]):
        product.append({(copy1[t] if b[t] else copy0[t]): p * x[t] / x[s]
                        for t, p in rows[s].items() if x[t] > 0})
    for s in (s for s in range(n) if after[s]):
        product.append({copy1[t]: p for t, p in rows[s].items()})
    start = [copy1[s] if b[s] else copy0.get(s, -1) for s in range(n)]
    return product, origin, start


def _expected(rows: Rows, rewards: Sequence[Fraction],
              target: Sequence[bool]) -> list[Fraction | float]:
    """PRISM's R=? [ F target ] in rationals (inf where target is not almost sure)."""
    n = len(rows)
    sure = [v == 1 for v in _until(rows, [True] * n, target)]
    unknown = [s for s in range(n) if sure[s] and not target[s]]
    values = _solve(rows, unknown, {s: rewards[s] for s in unknown}, [Fraction(0)] * n)
    return [values.get(s, Fraction(0)) if sure[s] else INF for s in range(n)]


def oracle(rows: Rows, rewards: Sequence[Fraction], a: Sequence[bool], b: Sequence[bool],
           state: int) -> dict[str, Fraction | float]:
    """P(F a | F b), P(G !a | F b), P(X a | F b), R(F a | F b) from *state*."""
    product, origin, start = _conditioned(rows, b)
    s = start[state]
    a_p = [a[o] for o in origin]
    reach = _until(product, [True] * len(product), a_p)[s]
    nxt = sum((p for t, p in product[s].items() if a_p[t]), Fraction(0))
    reward = _expected(product, [rewards[o] for o in origin], a_p)[s]
    return {"F": reach, "G": 1 - reach, "X": nxt, "R": reward}


# ---------------------------------------------------------------------------
# Random chains with dyadic probabilities
# ---------------------------------------------------------------------------


def _random_chain(seed: int) -> tuple[Rows, list[Fraction], list[bool], list[bool]]:
    rng = random.Random(seed)
    n = rng.randint(5, 9)
    rows: Rows = []
    for s in range(n):
        if s >= n - 2 and rng.random() < 0.7:
            rows.append({s: Fraction(1)})
            continue
        targets = rng.sample(range(n), rng.randint(1, 3))
        cuts = sorted(rng.sample(range(1, 16), len(targets) - 1))
        parts = [b - a for a, b in zip([0, *cuts], [*cuts, 16], strict=True)]
        rows.append({t: Fraction(p, 16) for t, p in zip(targets, parts, strict=True)})
    rewards = [Fraction(rng.randint(0, 4)) for _ in range(n)]
    a = [s == n - 1 or (s == n - 3 and rng.random() < 0.5) for s in range(n)]
    b = [s == n - 2 or (s == 1 and rng.random() < 0.5) for s in range(n)]
    return rows, rewards, a, b


def _prism(rows: Rows, rewards: Sequence[Fraction], a: Sequence[bool], b: Sequence[bool]) -> str:
    n = len(rows)
    lines = ["dtmc", "module m", f"  s : [0..{n - 1}] init 0;"]
    for s, row in enumerate(rows):
        updates = " + ".join(f"{p.numerator}/{p.denominator}:(s'={t})" for t, p in row.items())
        lines.append(f"  [] s={s} -> {updates};")
    lines += ["endmodule", 'rewards "r"']
    lines += [f"  s={s} : {int(r)};" for s, r in enumerate(rewards) if r]
    lines += ["endrewards"]
    for name, mask in (("a", a), ("b", b)):
        members = "|".join(f"s={s}" for s in range(n) if mask[s]) or "false"
        lines.append(f'label "{name}" = {members};')
    return "\n".join(lines) + "\n"


PROPS = {"F": 'P=? [ F "a" || F "b" ]', "G": 'P=? [ G !"a" || F "b" ]',
         "X": 'P=? [ X "a" || F "b" ]', "R": 'R{"r"}=? [ F "a" || F "b" ]'}


def _contains(result: CheckResult, expected: Fraction | float) -> bool:
    if expected == INF:
        return result.value == INF and result.upper == INF
    assert result.lower is not None and result.upper is not None
    return Fraction(result.lower) <= expected <= Fraction(result.upper)


@pytest.mark.parametrize("seed", range(24))
def test_random_chains_intervals_hold_the_rational_answer(seed: int) -> None:
    rows, rewards, a, b = _random_chain(seed)
    model = _prism(rows, rewards, a, b)
    if _until(rows, [True] * len(rows), b)[0] == 0:
        with pytest.raises(CheckError, match="has probability 0"):
            check_prism_file(model, props_source=PROPS["F"])
        return
    expected = oracle(rows, rewards, a, b, 0)
    props = ";\n".join(PROPS.values())
    floats = check_prism_file(model, props_source=props).results
    exact = check_prism_file(model, props_source=props, exact=True).results
    for key, plain, rational in zip(PROPS, floats, exact, strict=True):
        assert _contains(plain, expected[key]), (key, plain, expected[key])
        assert plain.precise, (key, plain)
        assert isinstance(rational, ExactCheckResult)
        if expected[key] == INF:
            assert rational.value == INF and rational.exact is None
        else:
            assert rational.exact == expected[key], key


def test_hand_chain_is_certified_and_exact() -> None:
    # test_conditional.py solves it by hand: E[t | succ] = 22/3 from s=0.
    prop = 'R{"t"}=? [ F "done" || F "succ" ]'
    (plain,) = check_prism_file(CHAIN, props_source=prop).results
    assert plain.precise and _contains(plain, Fraction(22, 3))
    assert plain.upper - plain.lower <= 1e-9 * 22 / 3
    (rational,) = check_prism_file(CHAIN, props_source=prop, exact=True).results
    assert isinstance(rational, ExactCheckResult) and rational.exact == Fraction(22, 3)


def test_infinite_given_the_condition() -> None:
    # From 0: to 1 or 2 (1/2 each); 1 is b and then loops forever without a; 2 is a.
    # Given F b the reward to a is infinite; given F a it is finite (1, one step).
    model = """dtmc
module m
  s : [0..3] init 0;
  [] s=0 -> 1/2:(s'=1) + 1/2:(s'=2);
  [] s=1 -> 1/2:(s'=1) + 1/2:(s'=3);
  [] s=2 -> true;
  [] s=3 -> true;
endmodule
rewards "r" s=0 : 1; s=1 : 1; endrewards
label "a" = s=2; label "b" = s=1;
"""
    results = check_prism_file(model, props_source='R{"r"}=? [ F "a" || F "b" ];\n'
                               'R{"r"}=? [ F "a" || F "a" ];\n'
                               'P=? [ F "a" || F "b" ]').results
    assert [r.value for r in results] == [INF, 1.0, 0.0]
    assert all(r.precise for r in results)


# ---------------------------------------------------------------------------
# Reward-bounded reachability on random dyadic chains: a path recursion in rationals
# ---------------------------------------------------------------------------


def _bounded_oracle(rows: Rows, rewards: Sequence[int], remain: Sequence[bool],
                    target: Sequence[bool], state: int, budget: int) -> Fraction:
    """P(remain U{r}<=budget target) by recursion over path prefixes (every state that
    can move has a positive reward, so the recursion ends)."""
    memo: dict[tuple[int, int], Fraction] = {}

    def go(s: int, left: int) -> Fraction:
        if target[s]:
            return Fraction(1)
        if not remain[s] or left - rewards[s] < 0 or rows[s] == {s: Fraction(1)}:
            return Fraction(0)
        key = (s, left)
        if key not in memo:
            memo[key] = sum((p * go(t, left - rewards[s]) for t, p in rows[s].items()),
                            Fraction(0))
        return memo[key]

    return go(state, budget)


@pytest.mark.parametrize("seed", range(12))
def test_reward_bounded_random_chains_certified_and_exact(seed: int) -> None:
    rows, _, a, b = _random_chain(100 + seed)
    rng = random.Random(seed)
    rewards = [Fraction(rng.randint(1, 3)) for _ in rows]
    model = _prism(rows, rewards, a, b)
    remain = [s != 2 for s in range(len(rows))]
    props = [f'P=? [ F{{"r"}}<={t} "a" ]' for t in (0, 3, 7, 12)] + ['P=? [ s!=2 U{"r"}<9 "a" ]']
    expected = [_bounded_oracle(rows, [int(r) for r in rewards], [True] * len(rows), a, 0, t)
                for t in (0, 3, 7, 12)]
    expected.append(_bounded_oracle(rows, [int(r) for r in rewards], remain, a, 0, 8))
    floats = check_prism_file(model, props_source=";\n".join(props)).results
    exact = check_prism_file(model, props_source=";\n".join(props), exact=True).results
    for prop, plain, rational, value in zip(props, floats, exact, expected, strict=True):
        assert _contains(plain, value) and plain.precise, (prop, plain.lower, plain.upper, value)
        assert isinstance(rational, ExactCheckResult) and rational.exact == value, prop


def test_reward_bounded_zero_reward_loop_is_certified() -> None:
    # s0 loops with reward 0 (1/2) or moves to s1 (reward 1), which wins w.p. 1/4 or
    # returns: P(F{r}<=k goal) = 1 - (3/4)^k, with a zero-reward closure on every level.
    model = """dtmc
module m
  s : [0..2] init 0;
  [] s=0 -> 1/2:(s'=0) + 1/2:(s'=1);
  [] s=1 -> 1/4:(s'=2) + 3/4:(s'=0);
  [] s=2 -> true;
endmodule
rewards "r" s=1 : 1; endrewards
label "goal" = s=2;
"""
    for k in (1, 5, 40):
        (plain,) = check_prism_file(model, props_source=f'P=? [ F{{"r"}}<={k} "goal" ]').results
        assert plain.precise and _contains(plain, 1 - Fraction(3, 4) ** k)
        (rational,) = check_prism_file(model, props_source=f'P=? [ F{{"r"}}<={k} "goal" ]',
                                       exact=True).results
        assert isinstance(rational, ExactCheckResult)
        assert rational.exact == 1 - Fraction(3, 4) ** k


# ---------------------------------------------------------------------------
# Storm's exact engine on a small emitted mission (conditional and reward-bounded)
# ---------------------------------------------------------------------------

STORM_PROPS = (
    'R{"mt"}=? [ F "done" || F "success" ]',
    'R{"rc"}=? [ F "done" || F "success" ]',
    'P=? [ F rc=1 || F "success" ]',
    'P=? [ F "success" || F rc=2 ]',
    'P=? [ F{"mt"}<=246 "success" ]',
    'P=? [ F{"rc"}<=1 "success" ]',
)


def test_small_mission_against_storm_exact(tmp_path: Path) -> None:
    text, storm = small_mission_storm_exact(tmp_path, STORM_PROPS)
    assert 0 < storm[3] < 1 and 0 < storm[4] < 1  # not trivial
    source = ";\n".join(STORM_PROPS)
    exact = check_prism_file(text, props_source=source, exact=True).results
    assert [r.exact for r in exact if isinstance(r, ExactCheckResult)] == storm
    floats = check_prism_file(text, props_source=source).results
    for plain, value in zip(floats, storm, strict=True):
        # The float model's entries are the decimals rounded, so its exact value may
        # differ from the rational model's by a few ulps: allow 1e-14 relative.
        assert plain.precise and plain.lower is not None and plain.upper is not None
        assert plain.lower * (1 - 1e-14) <= value <= plain.upper * (1 + 1e-14)
