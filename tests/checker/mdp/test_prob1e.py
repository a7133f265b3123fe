"""Prob1E (Pmax = 1) against the textbook nested fixpoint, on ladders and random MDPs."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest

from tests.checker.mdp.models import Choices, mask, mdp_from
from veribattery.checker.mdp import graph as graph_module
from veribattery.checker.mdp.graph import ChoiceGraph, almost_surely, prob1e


def _reference(choices: Choices, remain: Sequence[bool], target: Sequence[bool],
               allowed: Sequence[bool]) -> list[int]:
    """Pmax = 1 by the definition's nested fixpoint, one state and one choice at a
    time: *u* shrinks to the states that reach *target* through ``remain & !target``
    with allowed choices whose successors all lie in *u*."""
    u = set(range(len(choices)))
    numbers = _choice_numbers(choices)
    while True:
        reached = {s for s in u if target[s]}
        grown = True
        while grown:
            grown = False
            for s in sorted(u - reached):
                if not remain[s] or target[s]:
                    continue
                if any(allowed[numbers[s][i]] and {t for t, _ in c} <= u
                       and {t for t, _ in c} & reached for i, c in enumerate(choices[s])):
                    reached.add(s)
                    grown = True
        if reached == u:
            return sorted(u)
        u = reached


def _choice_numbers(choices: Choices) -> list[list[int]]:
    numbers, next_number = [], 0
    for state in choices:
        numbers.append(list(range(next_number, next_number + len(state))))
        next_number += len(state)
    return numbers


def _ladder(n: int, exit_at: int | None) -> Choices:
    """Rungs 0..n-1, the goal n, a trap n+1: rung i goes to the goal or to rung i-1
    (rung 0 to the trap) with probability 1/2 each; rung *exit_at* may also go to the
    goal surely."""
    goal, trap = n, n + 1
    rungs: list[list[list[tuple[int, float]]]] = [
        [[(goal, 0.5), (i - 1 if i else trap, 0.5)]] for i in range(n)]
    if exit_at is not None:
        rungs[exit_at].append([(goal, 1.0)])
    return [*rungs, [[(goal, 1.0)]], [[(trap, 1.0)]]]


def _random_choices(rng: np.random.Generator, n: int) -> Choices:
    """States with one to three choices of one to three successors, mostly nearby
    (so that cycles, hence end components, are common)."""
    states = []
    for s in range(n):
        state = []
        for _ in range(int(rng.integers(1, 4))):
            width = int(rng.integers(1, 4))
            near = (s + rng.integers(-3, 4, size=width)) % n
            far = rng.integers(0, n, size=width)
            successors = sorted(set(np.where(rng.random(width) < 0.8, near, far).tolist()))
            state.append([(int(t), 1.0 / len(successors)) for t in successors])
        states.append(state)
    return states


@pytest.mark.parametrize("exit_at", [None, 0, 3, 7])
def test_ladder_is_decided_in_two_searches(monkeypatch: pytest.MonkeyPatch,
                                           exit_at: int | None) -> None:
    n = 8
    searches = []
    original = graph_module.reached_from_root

    def counting(*args: Any) -> Any:
        searches.append(1)
        return original(*args)

    monkeypatch.setattr(graph_module, "reached_from_root", counting)
    mdp = mdp_from(_ladder(n, exit_at))
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    sure = prob1e(graph, np.ones(n + 2, dtype=bool), mask(n + 2, [n]))
    # From rung i, the goal is sure exactly when a rung at or below it can exit
    # surely: else the walk down ends in the trap with probability 2^-(i+1).
    expected = [] if exit_at is None else list(range(exit_at, n))
    assert np.flatnonzero(sure).tolist() == [*expected, n]
    # One search, then the rungs below the exit fall together; one more confirms.
    assert len(searches) == 2


@pytest.mark.parametrize("seed", range(60))
def test_prob1e_is_the_nested_fixpoint(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 30))
    choices = _random_choices(rng, n)
    mdp = mdp_from(choices)
    target = rng.random(n) < 0.1
    remain = rng.random(n) < 0.85
    allowed = rng.random(mdp.num_choices) < 0.85
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    for permitted in (None, allowed):
        sure = prob1e(graph, remain, target, permitted)
        every = np.ones(mdp.num_choices, dtype=bool) if permitted is None else permitted
        assert np.flatnonzero(sure).tolist() == _reference(choices, remain.tolist(),
                                                           target.tolist(), every.tolist())


@pytest.mark.parametrize("seed", range(20))
def test_almost_sure_witnesses_stay_and_progress(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(4, 30))
    mdp = mdp_from(_random_choices(rng, n))
    target = rng.random(n) < 0.1
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    sure, via = almost_surely(graph, np.ones(n, dtype=bool), target)
    inside = np.flatnonzero(sure & ~target)
    # Each witness keeps every successor in the set, and the witnesses' graph
    # reaches the target from every state of it (hence almost surely).
    assert np.all(mdp.choice_owner[via[inside]] == inside)
    reached = target.copy()
    for _ in range(n):
        for s in inside:
            row = mdp.transitions[via[s]]
            assert sure[row.indices].all()
            reached[s] |= reached[row.indices].any()
    assert reached[inside].all()
