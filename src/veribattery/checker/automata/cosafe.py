"""The automaton of a co-safe formula's good prefixes, as PRISM reads a reward's path.

``R [ psi ]`` accumulates reward until *psi* is satisfied: until the path's prefix so far
guarantees *psi*, whatever follows. PRISM decides that on the formula's structure, not on
its meaning alone: every proposition, ``true`` included, is settled by reading the letter
of its position -- ``R [ X X X true ]`` collects the rewards of three steps, not none,
although ``X X X true`` holds on every path; ``R [ (X X true) U s=3 ]`` waits until the
last ``X X true`` met before ``s=3`` is settled (PRISM's ``dtmc_rewards`` tests).

So a state here is what is still owed: a set of alternatives, each a set of formulas the
rest of the path must satisfy (negation normal form, over propositions, their negations,
``&``, ``|``, ``X`` and ``U``). Reading a letter expands every formula owed at that
position -- a proposition is settled by the letter, ``X a`` owes ``a`` next, ``a U b`` is
settled by ``b`` or owes ``a`` now and ``a U b`` next -- and the state is *accepting* once
some alternative owes nothing: the prefix read is then a good prefix, and the reward of
its last state is not counted (as for ``F``). An empty set of alternatives can never be
satisfied (the reward is infinite from there). Alternatives that contain another are
dropped: what they owe is owed by the smaller one too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from itertools import product as pairs

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.checker.automata import formula as ltl
from veribattery.checker.automata._limit import AutomatonTooLarge, check_size

__all__ = ["AutomatonTooLarge", "CosafeAutomaton", "NotCosafe", "cosafe_automaton"]

Owed = frozenset[ltl.LtlFormula]
State = frozenset[Owed]


@dataclass(frozen=True, slots=True)
class CosafeAutomaton:
    """A deterministic automaton on finite prefixes: ``successor[q, letter]``; the prefix
    read so far is good in the *accepting* states (which are closed: they stay so)."""

    initial: int
    successor: IntArray
    accepting: BoolArray


class NotCosafe(ValueError):
    """The formula is not syntactically co-safe (:func:`formula.is_syntactically_cosafe`)."""


def cosafe_automaton(formula: ltl.LtlFormula, alphabet: Sequence[int], *,
                     max_states: int = 100_000) -> CosafeAutomaton:
    """The good-prefix automaton of *formula* reading the letters of *alphabet* (column
    ``j`` of its table reads ``alphabet[j]``; bit *i* of a letter: proposition *i*).

    :raises NotCosafe: where *formula* is not syntactically co-safe.
    :raises AutomatonTooLarge: over *max_states* states.
    """
    if not ltl.is_syntactically_cosafe(formula):
        raise NotCosafe("not co-safe")
    start: State = frozenset({frozenset({_normal(formula, negated=False)})})
    number: dict[State, int] = {start: 0}
    rows: list[list[int]] = []
    queue = [start]
    while len(rows) < len(queue):
        state = queue[len(rows)]
        row = []
        for letter in alphabet:
            after = _read(state, letter)
            if after not in number:
                number[after] = len(number)
                check_size(len(number), max_states, "good-prefix automaton of the formula")
                queue.append(after)
            row.append(number[after])
        rows.append(row)
    accepting = np.array([frozenset() in state for state in queue], dtype=bool)
    return CosafeAutomaton(0, np.array(rows, dtype=np.int64), accepting)


def _read(state: State, letter: int) -> State:
    """What is owed after the position of *letter*, given what *state* owes there."""
    if frozenset() in state:
        return frozenset({frozenset()})
    found: set[Owed] = set()
    for alternative in state:
        options: set[Owed] = {frozenset()}
        for owed in alternative:
            options = {a | b for a, b in pairs(options, _expanded(owed, letter))}
            if not options:
                break
        found |= options
    return frozenset(a for a in found if not any(b < a for b in found))


@cache
def _expanded(formula: ltl.LtlFormula, letter: int) -> frozenset[Owed]:
    """The alternatives of what *formula*, owed at a position of *letter*, owes next."""
    match formula:
        case ltl.Const(value=value):
            return frozenset({frozenset()}) if value else frozenset()
        case ltl.Prop(index=index):
            return frozenset({frozenset()}) if letter >> index & 1 else frozenset()
        case ltl.Not(operand=ltl.Prop(index=index)):
            return frozenset() if letter >> index & 1 else frozenset({frozenset()})
        case ltl.And(left=left, right=right):
            return frozenset(a | b for a, b in pairs(_expanded(left, letter),
                                                     _expanded(right, letter)))
        case ltl.Or(left=left, right=right):
            return _expanded(left, letter) | _expanded(right, letter)
        case ltl.Next(operand=operand):
            return frozenset({frozenset({operand})})
        case ltl.Until(left=left, right=right):
            later = frozenset(a | {formula} for a in _expanded(left, letter))
            return _expanded(right, letter) | later
    raise TypeError(f"not in co-safe negation normal form: {formula!r}")


def _normal(formula: ltl.LtlFormula, *, negated: bool) -> ltl.LtlFormula:
    """*formula* (negated if *negated*) with negations pushed onto the propositions, and
    nothing else rewritten: folding ``X true`` into ``true`` (as :mod:`._simplify` may,
    the language being the same) would settle it a letter early. Called on co-safe
    formulas only, where no release remains."""
    match formula:
        case ltl.Const(value=value):
            return ltl.Const(value != negated)
        case ltl.Prop():
            return ltl.Not(formula) if negated else formula
        case ltl.Not(operand=operand):
            return _normal(operand, negated=not negated)
        case ltl.And(left=left, right=right) | ltl.Or(left=left, right=right):
            a, b = _normal(left, negated=negated), _normal(right, negated=negated)
            conjunction = isinstance(formula, ltl.And) != negated
            return ltl.And(a, b) if conjunction else ltl.Or(a, b)
        case ltl.Next(operand=operand):
            return ltl.Next(_normal(operand, negated=negated))
        case ltl.Until(left=left, right=right) if not negated:
            return ltl.Until(_normal(left, negated=False), _normal(right, negated=False))
        case ltl.Release(left=left, right=right) if negated:
            return ltl.Until(_normal(left, negated=True), _normal(right, negated=True))
    raise TypeError(f"not a co-safe LTL formula: {formula!r}")
