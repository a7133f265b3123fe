"""Deterministic parity automata of LTL formulas, for the product with a Markov model.

:func:`parity_automaton` chains the stages: negation normal form and simplification
(:mod:`._simplify`), a tableau to a transition-based Büchi automaton (:mod:`._tableau`,
Gerth-Peled-Vardi-Wolper / Couvreur), Safra-Piterman determinisation to transition-based
priorities (:mod:`._safra`), then state-based priorities and minimisation
(:mod:`._minimise`).

Reading convention: the run on ``w0 w1 ...`` is ``q0 = initial``,
``q(i+1) = successor[q(i), w(i)]``; the word is accepted iff the least priority among
the states ``q1, q2, ...`` occurring infinitely often is even.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from veribattery.checker.automata._limit import AutomatonTooLarge
from veribattery.checker.automata._minimise import minimise, normalise_priorities, state_based
from veribattery.checker.automata._safra import determinise
from veribattery.checker.automata._simplify import normal_form
from veribattery.checker.automata._tableau import buchi_automaton
from veribattery.checker.automata.formula import (
    And,
    Const,
    LtlFormula,
    Next,
    Not,
    Or,
    Prop,
    Release,
    Until,
)


@dataclass(frozen=True)
class ParityAutomaton:
    """A complete deterministic automaton with state-based min-parity acceptance.

    Letters are ``0 .. 2**propositions - 1``, bit ``i`` set iff ``Prop(i)`` holds; the
    automaton reads those in *letters* (all of them, in order, when None), column ``j``
    of *successor* being ``letters[j]``: a model whose states show a few of the letters
    needs an automaton over those only (the construction visits every letter of every
    state, 2^k of them).
    """

    propositions: int
    initial: int
    successor: NDArray[np.int32]  # (states, letters)
    priority: NDArray[np.int16]  # (states,)
    letters: tuple[int, ...] | None = None

    def complement(self) -> ParityAutomaton:
        """The automaton of the other words: the same graph, every priority one higher."""
        return ParityAutomaton(self.propositions, self.initial, self.successor,
                               (self.priority + 1).astype(np.int16), self.letters)

    def column(self, letter: int) -> int:
        """The column of *successor* that reads *letter*."""
        if self.letters is None:
            if not 0 <= letter < 1 << self.propositions:
                raise ValueError(f"letters must lie in 0..{(1 << self.propositions) - 1}")
            return letter
        if letter not in self.letters:
            raise ValueError(f"letter {letter} is not in the automaton's alphabet")
        return self.letters.index(letter)

    def accepts_lasso(self, prefix: Sequence[int], cycle: Sequence[int]) -> bool:
        """Whether the word ``prefix cycle cycle cycle ...`` is accepted."""
        if not cycle:
            raise ValueError("the cycle of a lasso word must not be empty")
        prefix = [self.column(letter) for letter in prefix]
        cycle = [self.column(letter) for letter in cycle]
        state = self.initial
        for letter in prefix:
            state = int(self.successor[state, letter])
        # The state at the start of each pass of the cycle repeats within #states passes;
        # from the first repetition on, the passes in between recur forever.
        seen: dict[int, int] = {}
        passes: list[int] = []  # least priority met during each pass
        while state not in seen:
            seen[state] = len(passes)
            least = None
            for letter in cycle:
                state = int(self.successor[state, letter])
                value = int(self.priority[state])
                least = value if least is None else min(least, value)
            assert least is not None
            passes.append(least)
        return min(passes[seen[state]:]) % 2 == 0


def parity_automaton(formula: LtlFormula, propositions: int, *,
                     alphabet: Sequence[int] | None = None,
                     max_states: int = 100_000) -> ParityAutomaton:
    """A deterministic parity automaton accepting exactly the words satisfying ``formula``.

    ``formula`` may use ``Prop(i)`` for ``0 <= i < propositions``. Raises
    :class:`AutomatonTooLarge` when a stage of the construction exceeds ``max_states``.

    :param alphabet: the letters to read (distinct), or None for all ``2**propositions``:
        on words over *alphabet* the automaton accepts exactly as the full one would.
    """
    if propositions < 0:
        raise ValueError(f"propositions must be >= 0, got {propositions}")
    # A proposition beyond the alphabet would silently read as false on every letter.
    outside = sorted(i for i in _indices(formula) if not 0 <= i < propositions)
    if outside:
        raise ValueError(f"the formula uses propositions {outside}, outside "
                         f"0..{propositions - 1}")
    letters = tuple(range(1 << propositions)) if alphabet is None else tuple(alphabet)
    if len(set(letters)) != len(letters) or not all(
            0 <= letter < 1 << propositions for letter in letters):
        raise ValueError(f"the alphabet must be distinct letters in 0..{(1 << propositions) - 1}")
    simple = normal_form(formula)
    buchi = buchi_automaton(simple, letters, max_states)
    dpa = determinise(buchi, len(letters), max_states)
    successor, priority = state_based(dpa, max_states)
    # Normalising can make states equal, and merging them can open more normalisation.
    while True:
        before = len(priority)
        successor, priority = minimise(successor, normalise_priorities(successor, priority))
        if len(priority) == before:
            break
    return ParityAutomaton(propositions, 0, successor, priority.astype(np.int16),
                           None if alphabet is None else letters)


def _indices(f: LtlFormula) -> set[int]:
    """The proposition indices occurring in ``f``."""
    match f:
        case Prop(index):
            return {index}
        case Const():
            return set()
        case Not(operand) | Next(operand):
            return _indices(operand)
        case And(a, b) | Or(a, b) | Until(a, b) | Release(a, b):
            return _indices(a) | _indices(b)
    raise TypeError(f"not an LTL formula: {f!r}")


__all__ = ["AutomatonTooLarge", "ParityAutomaton", "parity_automaton"]
