"""The good-prefix automaton of a co-safe formula, read letter by letter.

A prefix is good when what the formula owes is settled by the letters read, each
proposition (``true`` too) by the letter of its own position: ``X X X true`` needs four
letters, as PRISM counts it, although it holds on every word.
"""

from __future__ import annotations

import pytest

from veribattery.checker.automata import formula as ltl
from veribattery.checker.automata.cosafe import NotCosafe, cosafe_automaton

A, B = ltl.Prop(0), ltl.Prop(1)
TRUE = ltl.Const(True)


def _settled_after(formula: ltl.LtlFormula, word: list[int]) -> int | None:
    """How many letters of *word* make a good prefix (None: none does; -1: cannot)."""
    automaton = cosafe_automaton(formula, [0, 1, 2, 3])
    state = automaton.initial
    for read, letter in enumerate(word, start=1):
        state = int(automaton.successor[state, letter])
        if automaton.accepting[state]:
            return read
    return None


@pytest.mark.parametrize(("formula", "word", "letters"), [
    (TRUE, [0, 0], 1),
    (ltl.Next(TRUE), [0, 0, 0], 2),
    (ltl.Next(ltl.Next(ltl.Next(TRUE))), [0] * 6, 4),
    (ltl.eventually(A), [0, 0, 1, 0], 3),
    (ltl.eventually(ltl.And(A, ltl.Next(B))), [1, 0, 1, 2, 0], 4),
    (ltl.Until(ltl.Next(ltl.Next(TRUE)), A), [0, 0, 0, 1, 0, 0], 5),  # the last X X true
    (ltl.Or(A, ltl.Next(TRUE)), [1, 0], 1),
    (ltl.Or(A, ltl.Next(TRUE)), [0, 0], 2),
    (ltl.Next(ltl.Const(False)), [0, 0, 0], None),
    (ltl.Not(ltl.globally(ltl.Not(A))), [0, 1], 2),  # = F a, once negations are pushed
])
def test_prefixes_are_good_once_every_obligation_is_read(
        formula: ltl.LtlFormula, word: list[int], letters: int | None) -> None:
    assert _settled_after(formula, word) == letters


def test_accepting_states_stay_accepting_and_failure_is_a_sink() -> None:
    automaton = cosafe_automaton(ltl.Next(A), [0, 1])
    after_one = int(automaton.successor[automaton.initial, 0])
    accepted = int(automaton.successor[after_one, 1])
    failed = int(automaton.successor[after_one, 0])
    assert automaton.accepting[accepted] and not automaton.accepting[failed]
    assert all(int(automaton.successor[accepted, c]) == accepted for c in (0, 1))
    assert all(int(automaton.successor[failed, c]) == failed for c in (0, 1))


@pytest.mark.parametrize("formula", [
    ltl.globally(A), ltl.weak_until(A, B), ltl.Not(ltl.eventually(A)), ltl.Release(A, B),
    ltl.eventually(ltl.globally(A)),
])
def test_formulas_with_a_release_left_are_not_cosafe(formula: ltl.LtlFormula) -> None:
    with pytest.raises(NotCosafe):
        cosafe_automaton(formula, [0, 1, 2, 3])


def test_the_alphabet_names_the_columns() -> None:
    automaton = cosafe_automaton(ltl.eventually(B), [2, 0])  # column 0 reads b
    assert automaton.accepting[int(automaton.successor[automaton.initial, 0])]
    assert not automaton.accepting[int(automaton.successor[automaton.initial, 1])]
