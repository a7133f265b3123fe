"""The parity automata against the direct LTL semantics of :mod:`.oracle` on lasso words.

Thousands of seeded random formulas (every operator, constants, W, =>, <=>; depth up to
5; 1 to 3 propositions), each on random lassos, plus PRISM's LTL test formulas on every
short lasso. The complement must accept exactly the other words.
"""

from __future__ import annotations

import itertools
import random

import pytest

from tests.checker.automata.oracle import holds, random_formula, random_lasso
from veribattery.checker.automata import (
    And,
    AutomatonTooLarge,
    Const,
    LtlFormula,
    Next,
    Not,
    Or,
    Prop,
    Release,
    Until,
    eventually,
    globally,
    iff,
    implies,
    parity_automaton,
    weak_until,
)

CHUNKS = 8
FORMULAS_PER_CHUNK = 400
LASSOS_PER_FORMULA = 10
#: Random formulas whose automaton outgrows this are skipped (a few; they would only
#: slow the suite down, the algorithm is the same).
BUDGET = 3000

A, B, C = Prop(0), Prop(1), Prop(2)
F, G, X = eventually, globally, Next

#: PRISM's LTL regression formulas (and a few more), with their proposition counts.
NAMED: dict[str, tuple[LtlFormula, int]] = {
    "G F a": (G(F(A)), 1),
    "F G a": (F(G(A)), 1),
    "(G !b) & (G F a)": (And(G(Not(B)), G(F(A))), 2),
    "G (a => ((a W b) W b))": (G(implies(A, weak_until(weak_until(A, B), B))), 2),
    "X X X a": (X(X(X(A))), 1),
    "F (a & X b)": (F(And(A, X(B))), 2),
    "(F G !a) & (G F b)": (And(F(G(Not(A))), G(F(B))), 2),
    "(G F a) => (F b & F c)": (implies(G(F(A)), And(F(B), F(C))), 3),
    "G F a <=> G F b": (iff(G(F(A)), G(F(B))), 2),
    "a W b": (weak_until(A, B), 2),
    "F G (a | X b)": (F(G(Or(A, X(B)))), 2),
    "a U (b R X a)": (Until(A, Release(B, X(A))), 2),
    "true": (Const(True), 1),
    "false": (Const(False), 1),
}


def _words(propositions: int, longest_prefix: int, longest_cycle: int):
    letters = range(1 << propositions)
    for u_len in range(longest_prefix + 1):
        for v_len in range(1, longest_cycle + 1):
            for u in itertools.product(letters, repeat=u_len):
                for v in itertools.product(letters, repeat=v_len):
                    yield list(u), list(v)


@pytest.mark.parametrize("name", list(NAMED))
def test_named_formulas_on_every_short_lasso(name: str) -> None:
    formula, k = NAMED[name]
    automaton = parity_automaton(formula, k)
    other = automaton.complement()
    longest_prefix, longest_cycle = (2, 3) if k <= 2 else (1, 2)
    count = 0
    for u, v in _words(k, longest_prefix, longest_cycle):
        expected = holds(formula, u, v)
        assert automaton.accepts_lasso(u, v) == expected, (name, u, v)
        assert other.accepts_lasso(u, v) != expected, (name, u, v)
        count += 1
    assert count > 80


@pytest.mark.parametrize("chunk", range(CHUNKS))
def test_random_formulas_on_random_lassos(chunk: int) -> None:
    rng = random.Random(1000 + chunk)
    skipped = 0
    for _ in range(FORMULAS_PER_CHUNK):
        k = rng.randrange(1, 4)
        formula = random_formula(rng, k, rng.randrange(1, 6))
        try:
            automaton = parity_automaton(formula, k, max_states=BUDGET)
        except AutomatonTooLarge:
            skipped += 1
            continue
        other = automaton.complement()
        for _ in range(LASSOS_PER_FORMULA):
            u, v = random_lasso(rng, k)
            expected = holds(formula, u, v)
            assert automaton.accepts_lasso(u, v) == expected, (formula, k, u, v)
            assert other.accepts_lasso(u, v) != expected, (formula, k, u, v)
    assert skipped <= FORMULAS_PER_CHUNK // 50


@pytest.mark.parametrize("chunk", range(2))
def test_negation_gives_the_complement(chunk: int) -> None:
    """``Not(f)``'s own automaton and ``f``'s complement agree on every sampled word."""
    rng = random.Random(2000 + chunk)
    for _ in range(150):
        k = rng.randrange(1, 3)
        formula = random_formula(rng, k, rng.randrange(1, 5))
        try:
            negated = parity_automaton(Not(formula), k, max_states=BUDGET)
            other = parity_automaton(formula, k, max_states=BUDGET).complement()
        except AutomatonTooLarge:
            continue
        for u, v in _words(k, 1, 2):
            assert negated.accepts_lasso(u, v) == other.accepts_lasso(u, v), (formula, u, v)


def test_oracle_on_hand_cases() -> None:
    """The oracle itself, on words whose verdict is plain."""
    assert holds(G(F(A)), [0, 0], [0, 1])
    assert not holds(G(F(A)), [1, 1], [0])
    assert holds(F(G(A)), [0, 0, 0], [1])
    assert not holds(F(G(A)), [1], [1, 0])
    assert holds(X(X(X(A))), [0, 0, 0, 1], [0])
    assert not holds(X(X(X(A))), [1, 1, 1], [0])
    assert holds(weak_until(A, B), [], [1])  # a forever
    assert not holds(F(B), [], [1])
