"""Bisimulation quotients: exact lumpings (checked in rationals), one partition per point,
certified answers that contain the chain's exact values, and no quotient for cycles."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from tests.checker.chains import dtmc
from veribattery._sparse import csr_sharing
from veribattery.checker import check
from veribattery.explore.dtmc import DTMC
from veribattery.explore.reuse.lumping import Lumper, Partition, dtmc_seeds, partition
from veribattery.lang import parse_property


def _fan(p: float, q: float) -> DTMC:
    """0 -> 1 (p) | 2 (1-p); 1 -> 3 (q) | 5; 2 -> 4 (q) | 6; 3, 4 "goal"; 5, 6 "miss".

    1 and 2 are bisimilar (as are 3 and 4, 5 and 6), but 0 reaches both: they must stay
    apart, or the quotient would need ``fl(p) + fl(1 - p)``."""
    rows = {0: {1: p, 2: 1 - p}, 1: {3: q, 5: 1 - q}, 2: {4: q, 6: 1 - q}}
    return dtmc(rows, 7, labels={"goal": [3, 4], "miss": [5, 6]},
                rewards={"steps": ([0.0] * 7, [1.0] * 3 + [0.0] * 4)})


def _ladder(rng: np.random.Generator, copies: int, depth: int) -> DTMC:
    """*copies* identical random acyclic gadgets of *depth* levels, entered from state 0
    with random weights: the copies lump together, their entries must not be summed."""
    size = 2 * depth + 2  # per copy: two states per level, then goal and miss
    n = 1 + copies * size
    weights = rng.integers(1, 10, copies)
    rows: dict[int, dict[int, float]] = {0: {1 + c * size: float(w) / float(weights.sum())
                                             for c, w in enumerate(weights)}}
    probabilities = rng.integers(1, 10, (depth, 2)) / 10.0
    for c in range(copies):
        base = 1 + c * size
        goal, miss = base + 2 * depth, base + 2 * depth + 1
        for level in range(depth):
            nxt = (base + 2 * level + 2, base + 2 * level + 3) if level + 1 < depth else (
                goal, miss)
            for side in range(2):
                here = base + 2 * level + side
                p = float(probabilities[level, side])
                rows[here] = {nxt[0]: p, nxt[1]: 1 - p} if side == 0 else {here: 0.25,
                                                                          nxt[0]: 0.75 * p,
                                                                          nxt[1]: 0.75 - 0.75 * p}
    goals = [1 + c * size + 2 * depth for c in range(copies)]
    misses = [g + 1 for g in goals]
    steps = [1.0 if s not in goals + misses else 0.0 for s in range(n)]
    return dtmc(rows, n, labels={"goal": goals, "end": goals + misses},
                rewards={"steps": ([0.0] * n, steps)})


def _exact_values(chain: DTMC, target: np.ndarray, reward: np.ndarray | None) -> list[Fraction]:
    """P(F target) (reward None) or the expected reward until target, in rationals, of
    the chain's float64 entries, by substitution from the sinks (the chain is acyclic
    apart from self-loops)."""
    P = chain.transitions
    n = chain.num_states
    value: list[Fraction | None] = [None] * n
    while any(v is None for v in value):
        for s in range(n):
            if value[s] is not None:
                continue
            row = {int(t): Fraction(float(p))
                   for t, p in zip(P.indices[P.indptr[s]:P.indptr[s + 1]],
                                   P.data[P.indptr[s]:P.indptr[s + 1]], strict=True)}
            if target[s]:
                value[s] = Fraction(1) if reward is None else Fraction(0)
                continue
            others = {t: p for t, p in row.items() if t != s}
            if not others:  # absorbing outside the target
                value[s] = Fraction(0)
                continue
            if any(value[t] is None for t in others):
                continue
            leave = sum(others.values(), Fraction(0))
            total = sum((p * value[t] for t, p in others.items()), Fraction(0))  # type: ignore[operator]
            if reward is not None:
                total += Fraction(float(reward[s]))
            value[s] = total / leave
    return value  # type: ignore[return-value]


def test_successors_of_one_state_are_never_summed() -> None:
    chain = _fan(0.1, 0.3)
    found = partition(chain, dtmc_seeds(chain, []))
    last = found.rounds[-1]
    assert len(found.rounds) == 2  # round 1 merged 1 and 2; they were split apart
    # {0} {1} {2} {3, 4} {5, 6}: 1 and 2 apart (0 reaches both), their successors together
    assert last.blocks == 5
    assert last.block[3] == last.block[4] and last.block[5] == last.block[6]
    assert len({last.block[0], last.block[1], last.block[2], last.block[3]}) == 4
    quotient = found.quotient(chain)
    # Every quotient entry is one of the chain's stored probabilities, not a sum.
    assert sorted(quotient.transitions.data.tolist()) == sorted(
        chain.transitions.data[np.isin(np.repeat(np.arange(7), np.diff(
            chain.transitions.indptr)), last.representative)].tolist())


@pytest.mark.parametrize("seed", range(6))
def test_quotient_is_an_exact_lumping(seed: int) -> None:
    chain = _ladder(np.random.default_rng(seed), copies=3, depth=4)
    found = partition(chain, dtmc_seeds(chain, []))
    assert found.rounds and found.blocks < chain.num_states
    last, quotient = found.rounds[-1], found.quotient(chain)
    P, Q = chain.transitions, quotient.transitions
    # P 1_C = 1_B Q_BC exactly, for every state and every block (rational sums).
    for s in range(chain.num_states):
        into: dict[int, Fraction] = {}
        for t, p in zip(P.indices[P.indptr[s]:P.indptr[s + 1]],
                        P.data[P.indptr[s]:P.indptr[s + 1]], strict=True):
            key = int(last.block[t])
            into[key] = into.get(key, Fraction(0)) + Fraction(float(p))
        b = last.block[s]
        expected = {int(c): Fraction(float(q)) for c, q in zip(
            Q.indices[Q.indptr[b]:Q.indptr[b + 1]], Q.data[Q.indptr[b]:Q.indptr[b + 1]],
            strict=True)}
        assert into == expected, s
        for name, mask in chain.labels.items():
            assert mask[s] == quotient.labels[name][b]


@pytest.mark.parametrize("seed", range(6))
def test_certified_answers_on_the_quotient_contain_the_exact_values(seed: int) -> None:
    chain = _ladder(np.random.default_rng(seed), copies=3, depth=4)
    quotient = partition(chain, dtmc_seeds(chain, [])).quotient(chain)
    cases = [('P=? [ F "goal" ]', chain.labels["goal"], None),
             ('R{"steps"}=? [ F "end" ]', chain.labels["end"], chain.rewards[0].total)]
    for text, target, reward in cases:
        exact = _exact_values(chain, target, reward)[0]
        on_chain = check(chain, parse_property(text), keep="answers")
        on_quotient = check(quotient, parse_property(text), keep="answers")
        assert Fraction(float(on_quotient.lower)) <= exact <= Fraction(float(on_quotient.upper))
        assert on_quotient.value == pytest.approx(on_chain.value, rel=1e-13, abs=0.0)


def test_a_later_point_reuses_the_partition_only_where_it_is_its_own() -> None:
    lumper = Lumper()
    first = _fan(0.1, 0.3)
    kept = _first_partition(lumper, first)
    # Another point of the pattern (the same index arrays, other probabilities).
    P = first.transitions
    second = _with_values(first, np.select([P.data == 0.3, P.data == 0.7], [0.4, 0.6], P.data))
    assert kept.fits(second.transitions)
    assert kept.holds(second.transitions, dtmc_seeds(second, []))
    moved = lumper.quotient(second, [])
    assert lumper._last is kept  # re-used
    # {0} {1} {2} {3, 4} {5, 6}: the new probabilities, the goal and miss blocks' loops
    assert moved is not None and sorted(moved.transitions.data.tolist()) == sorted(
        [0.1, 0.9, 0.4, 0.6, 0.4, 0.6, 1.0, 1.0])


def test_a_point_with_coarser_blocks_gets_its_own_partition() -> None:
    # Two gadgets that differ only in their probabilities: apart at q = 0.3 / 0.4,
    # bisimilar where both are 0.5.
    def chain(q1: float, q2: float) -> DTMC:
        rows = {0: {1: 0.5, 9: 0.5}, 9: {2: 1.0}, 1: {3: q1, 4: 1 - q1},
                2: {5: q2, 6: 1 - q2}, 3: {7: 1.0}, 5: {8: 1.0}}
        return dtmc(rows, 10, labels={"goal": [7, 8], "miss": [4, 6]})

    lumper = Lumper()
    apart = chain(0.3, 0.4)
    kept = _first_partition(lumper, apart)
    P = apart.transitions
    same = _with_values(apart, np.where(np.isin(P.data, (0.3, 0.4, 0.7, 0.6)), 0.5, P.data))
    assert not kept.holds(same.transitions, dtmc_seeds(same, []))
    lumper.quotient(same, [])
    again = lumper._last
    assert again is not kept and again is not None
    fresh = partition(same, dtmc_seeds(same, []))
    assert np.array_equal(again.rounds[-1].block, fresh.rounds[-1].block)
    assert again.blocks < kept.blocks  # 1 and 2 (and 3 and 5) merge at 0.5
    # The next point like the first finds the first partition again, made no more.
    lumper.quotient(_with_values(apart, P.data.copy()), [])
    assert lumper._last is kept


def _with_values(chain: DTMC, values: np.ndarray) -> DTMC:
    """*chain* at another point: other probabilities on the very same index arrays."""
    P = chain.transitions
    return DTMC(csr_sharing(values, P.indices, P.indptr, P.shape), chain.states,
                chain.variable_names, chain.initial, chain.labels, chain.rewards)


def _first_partition(lumper: Lumper, chain: DTMC) -> Partition:
    lumper.quotient(chain, [])
    kept = lumper._last
    assert kept is not None
    return kept


def test_seeds_keep_apart_what_the_properties_read() -> None:
    chain = _fan(0.1, 0.3)  # the variable s numbers the states: nothing merges
    assert partition(chain, dtmc_seeds(chain, ["s"])).blocks == chain.num_states


def test_no_quotient_with_a_cycle() -> None:
    chain = dtmc({0: {1: 0.5, 2: 0.5}, 1: {0: 0.5, 3: 0.5}, 2: {0: 0.5, 3: 0.5}}, 4,
                 labels={"goal": [3]})
    found = partition(chain, dtmc_seeds(chain, []))
    assert found.rounds == () and not found.worth(chain.num_states)
    assert Lumper().quotient(chain, []) is None


def test_a_point_where_members_disagree_gets_its_own_partition() -> None:
    lumper = Lumper()
    first = _fan(0.1, 0.3)
    kept = _first_partition(lumper, first)
    P = first.transitions
    values = P.data.copy()
    values[P.indptr[2]:P.indptr[3]] = (0.35, 0.65)  # state 2 no longer moves as 1 does
    other = _with_values(first, values)
    assert not kept.holds(other.transitions, dtmc_seeds(other, []))
    lumper.quotient(other, [])
    fresh = partition(other, dtmc_seeds(other, []))
    assert lumper._last is not kept and lumper._last is not None
    assert np.array_equal(lumper._last.rounds[-1].block, fresh.rounds[-1].block)
    # Seeds that change at a point are checked too: a reward that differs in 4 only.
    steps = np.asarray(first.rewards[0].transition).copy()
    steps[4] = 2.0
    rewarded = DTMC(P, first.states, first.variable_names, first.initial, first.labels,
                    (type(first.rewards[0])("steps", first.rewards[0].state, steps),))
    assert not kept.holds(rewarded.transitions, dtmc_seeds(rewarded, []))
