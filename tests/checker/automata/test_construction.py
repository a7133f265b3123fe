"""Hand-checked automata, the co-safety rule, the state budget and the table layout."""

from __future__ import annotations

import numpy as np
import pytest

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
    Release,
    Until,
    eventually,
    globally,
    iff,
    implies,
    is_syntactically_cosafe,
    parity_automaton,
    weak_until,
)

A, B, C = Prop(0), Prop(1), Prop(2)
F, G, X = eventually, globally, Next


def test_sugar_builds_core_nodes() -> None:
    assert F(A) == Until(Const(True), A)
    assert G(A) == Release(Const(False), A)
    assert weak_until(A, B) == Release(B, Or(A, B))
    assert implies(A, B) == Or(Not(A), B)
    assert iff(A, B) == Or(And(A, B), And(Not(A), Not(B)))


def test_globally_eventually_has_two_states() -> None:
    automaton = parity_automaton(G(F(A)), 1)
    assert len(automaton.priority) == 2
    # Reading a leads to the even state, reading !a to the odd one, from anywhere.
    even = int(automaton.successor[automaton.initial, 1])
    odd = int(automaton.successor[automaton.initial, 0])
    assert automaton.priority[even] % 2 == 0 and automaton.priority[odd] % 2 == 1
    assert automaton.successor.tolist() == [[odd, even]] * 2


def test_constants_have_one_state() -> None:
    yes, no = parity_automaton(Const(True), 2), parity_automaton(Const(False), 2)
    assert yes.successor.tolist() == [[0, 0, 0, 0]] and yes.priority[0] % 2 == 0
    assert no.successor.tolist() == [[0, 0, 0, 0]] and no.priority[0] % 2 == 1
    assert parity_automaton(G(Or(A, Not(A))), 1).successor.shape == (1, 2)


@pytest.mark.parametrize(("formula", "k", "states"), [
    (F(A), 1, 2),  # waiting, then the accepting sink
    (G(A), 1, 2),  # safe, then the rejecting sink
    (X(A), 1, 4),  # initial, after one letter, the two sinks
    (X(X(X(A))), 1, 6),
    (Until(A, B), 2, 3),
    (F(And(A, X(B))), 2, 3),
    (F(G(A)), 1, 3),
    (And(G(Not(B)), G(F(A))), 2, 3),
    (G(implies(A, weak_until(weak_until(A, B), B))), 2, 3),
    (And(F(G(Not(A))), G(F(B))), 2, 3),
])
def test_sizes(formula: LtlFormula, k: int, states: int) -> None:
    """Sizes as built (hand-checked minimal where noted; the rest pin regressions)."""
    assert len(parity_automaton(formula, k).priority) == states


def test_initial_priority_counts_only_if_the_initial_state_recurs() -> None:
    # F a: the initial state is the waiting state; reading a leaves it for good.
    automaton = parity_automaton(F(A), 1)
    assert automaton.accepts_lasso([0, 0], [1])
    assert not automaton.accepts_lasso([], [0])
    hand = ParityAutomaton(1, 0, np.array([[1, 1], [1, 1]], dtype=np.int32),
                           np.array([1, 0], dtype=np.int16))
    assert hand.accepts_lasso([], [0])  # state 0 (odd) is never visited again


def test_table_layout() -> None:
    automaton = parity_automaton(implies(G(F(A)), And(F(B), F(C))), 3)
    assert automaton.propositions == 3
    assert automaton.successor.dtype == np.int32 and automaton.successor.shape[1] == 8
    assert automaton.priority.dtype == np.int16
    assert automaton.successor.shape[0] == automaton.priority.shape[0]
    assert 0 <= automaton.initial < automaton.successor.shape[0]
    assert automaton.successor.min() >= 0
    assert automaton.successor.max() < automaton.successor.shape[0]
    other = automaton.complement()
    assert np.array_equal(other.successor, automaton.successor)
    assert np.array_equal(other.priority, automaton.priority + 1)
    assert other.priority.dtype == np.int16


def test_unused_propositions_widen_the_alphabet() -> None:
    automaton = parity_automaton(F(A), 3)
    assert automaton.successor.shape[1] == 8
    assert automaton.accepts_lasso([6, 6, 7], [0]) and not automaton.accepts_lasso([], [6])


@pytest.mark.parametrize("formula", [
    F(A), Until(A, B), X(X(A)), F(And(A, X(B))), Not(G(A)), Const(True), Not(A),
    And(F(A), Or(B, X(Until(A, Not(B))))), Not(Release(Not(A), B)),
])
def test_cosafe(formula: LtlFormula) -> None:
    assert is_syntactically_cosafe(formula)


@pytest.mark.parametrize("formula", [
    G(A), F(G(A)), weak_until(A, B), Not(F(A)), Release(A, B), Not(Until(A, B)),
    G(F(A)), implies(F(A), F(B)), iff(F(A), B),
])
def test_not_cosafe(formula: LtlFormula) -> None:
    assert not is_syntactically_cosafe(formula)


def test_too_large_says_how_many_and_the_limit() -> None:
    formula = implies(G(F(A)), And(F(B), F(C)))
    with pytest.raises(AutomatonTooLarge, match=r"reached \d+ states.*max_states=5"):
        parity_automaton(formula, 3, max_states=5)
    assert issubclass(AutomatonTooLarge, ValueError)
    parity_automaton(formula, 3, max_states=10_000)


def test_bad_input() -> None:
    automaton = parity_automaton(F(A), 1)
    with pytest.raises(ValueError, match="cycle"):
        automaton.accepts_lasso([1], [])
    with pytest.raises(ValueError, match="letters"):
        automaton.accepts_lasso([2], [0])
    with pytest.raises(ValueError):
        parity_automaton(F(A), -1)
    with pytest.raises(ValueError, match=r"propositions \[1\]"):
        parity_automaton(Or(B, Not(B)), 1)
