"""``universal_states`` against the oracle, both ways, and on hand-checked cases.

A state reached after a prefix ``u`` is universal iff every continuation of ``u`` is a
model. If it is, random continuations must all satisfy the formula; if it is not, the
test builds a rejecting continuation itself (a path to a cycle whose least priority is
odd, found by search in the test, not by the code under test) and the oracle must
reject it. For co-safe formulas a word is a model iff one of its prefixes reaches a
universal state (a good prefix).
"""

from __future__ import annotations

import random
from collections import deque

import numpy as np

from tests.checker.automata.oracle import holds, random_formula, random_lasso
from veribattery.checker.automata import (
    And,
    AutomatonTooLarge,
    Const,
    LtlFormula,
    Next,
    Not,
    Or,
    ParityAutomaton,
    Prop,
    Until,
    eventually,
    globally,
    parity_automaton,
)

A, B = Prop(0), Prop(1)


def _run(automaton: ParityAutomaton, letters: list[int]) -> int:
    state = automaton.initial
    for letter in letters:
        state = int(automaton.successor[state, letter])
    return state


def _path(automaton: ParityAutomaton, start: int, goal: int, allowed: np.ndarray,
          *, nonempty: bool) -> list[int] | None:
    """Letters of a shortest path from ``start`` to ``goal`` through allowed states."""
    came: dict[int, tuple[int, int]] = {}
    queue = deque([start])
    if not nonempty and start == goal:
        return []
    while queue:
        state = queue.popleft()
        for letter, target in enumerate(automaton.successor[state].tolist()):
            if not allowed[target] or target in came:
                continue
            came[target] = (state, letter)
            if target == goal:
                letters = []
                while True:
                    source, step = came[target]
                    letters.append(step)
                    target = source
                    if target == start and len(letters) > 0:
                        return letters[::-1]
            queue.append(target)
    return None


def _rejected_continuation(automaton: ParityAutomaton,
                           state: int) -> tuple[list[int], list[int]] | None:
    """A word ``path cycle^omega`` rejected from ``state``, if any: brute force."""
    everywhere = np.ones(len(automaton.priority), dtype=bool)
    for p in sorted(set(automaton.priority.tolist())):
        if p % 2 == 0:
            continue
        for goal in np.flatnonzero(automaton.priority == p).tolist():
            lead = _path(automaton, state, goal, everywhere, nonempty=False)
            if lead is None:
                continue
            cycle = _path(automaton, goal, goal, automaton.priority >= p, nonempty=True)
            if cycle is not None:
                return lead, cycle
    return None


def _cosafe_formula(rng: random.Random, k: int, depth: int) -> LtlFormula:
    """A random formula of the co-safe fragment (literals, and, or, X, U, F)."""
    if depth == 0 or rng.random() < 0.2:
        leaf = Prop(rng.randrange(k))
        return Not(leaf) if rng.random() < 0.3 else leaf
    choice = rng.randrange(5)
    left, right = (_cosafe_formula(rng, k, depth - 1) for _ in range(2))
    return [And(left, right), Or(left, right), Next(left), Until(left, right),
            eventually(left)][choice]


def test_universal_states_agree_with_the_oracle() -> None:
    rng = random.Random(7)
    universal_seen = rejected_seen = 0
    for _ in range(400):
        k = rng.randrange(1, 3)
        formula = random_formula(rng, k, rng.randrange(1, 5))
        try:
            automaton = parity_automaton(formula, k, max_states=2000)
        except AutomatonTooLarge:
            continue
        universal = automaton.universal_states()
        assert universal.dtype == np.bool_ and universal.shape == automaton.priority.shape
        for _ in range(3):
            u = random_lasso(rng, k)[0]
            state = _run(automaton, u)
            witness = _rejected_continuation(automaton, state)
            assert universal[state] == (witness is None), (formula, u)
            if witness is None:
                universal_seen += 1
                for _ in range(6):
                    more, cycle = random_lasso(rng, k)
                    assert holds(formula, u + more, cycle), (formula, u, more, cycle)
            else:
                rejected_seen += 1
                lead, cycle = witness
                assert not holds(formula, u + lead, cycle), (formula, u, lead, cycle)
    assert universal_seen > 100 and rejected_seen > 100


def test_cosafe_models_are_those_with_a_good_prefix() -> None:
    rng = random.Random(8)
    for _ in range(300):
        k = rng.randrange(1, 3)
        formula = _cosafe_formula(rng, k, rng.randrange(1, 5))
        automaton = parity_automaton(formula, k)
        universal = automaton.universal_states()
        horizon = len(automaton.priority) + 1
        for _ in range(8):
            u, v = random_lasso(rng, k)
            state, good = automaton.initial, bool(universal[automaton.initial])
            for letter in u + v * horizon:
                state = int(automaton.successor[state, letter])
                good = good or bool(universal[state])
            assert good == holds(formula, u, v), (formula, u, v)


def test_hand_checked_good_prefixes() -> None:
    fa = parity_automaton(eventually(A), 1)
    universal = fa.universal_states()
    assert not universal[fa.initial]
    assert not universal[_run(fa, [0, 0, 0])]
    assert universal[_run(fa, [1])] and universal[_run(fa, [0, 0, 1])]

    # X X a: a at position 2, i.e. in the third letter read.
    xxa = parity_automaton(Next(Next(A)), 1)
    universal = xxa.universal_states()
    assert not universal[_run(xxa, [1, 1])]
    assert universal[_run(xxa, [0, 0, 1])]
    assert not universal[_run(xxa, [1, 1, 0])]

    ga = parity_automaton(globally(A), 1)
    assert not ga.universal_states().any()

    fab = parity_automaton(eventually(And(A, Next(B))), 2)
    universal = fab.universal_states()
    assert not universal[_run(fab, [1])] and universal[_run(fab, [1, 2])]
    assert not universal[_run(fab, [1, 1, 0])]

    assert parity_automaton(Const(True), 2).universal_states().all()
    assert not parity_automaton(Const(False), 2).universal_states().any()
