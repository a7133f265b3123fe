"""The automaton of an LTL path formula, and the column of its table each state reads.

The automaton is built over the letters the model's states show only (a state's letter
being the set of propositions that hold there): the construction visits every letter of
every automaton state, and a model shows far fewer than the 2^k sets of k propositions
(``s=1``, ``s=2``, ``s=3`` never hold together). On the model's paths the automaton
reads exactly as the one over all letters.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.checker.automata.cosafe import CosafeAutomaton, NotCosafe, cosafe_automaton
from veribattery.checker.automata.formula import is_syntactically_cosafe
from veribattery.checker.automata.parity import AutomatonTooLarge, ParityAutomaton, parity_automaton
from veribattery.checker.ltl.propositions import letters, propositions
from veribattery.errors import CheckError, Span
from veribattery.lang.nodes import CosafeReach, Expr, LtlNode

__all__ = ["StateSet", "cosafe_of", "cosafe_refusal", "parity_of"]

#: The states satisfying a state formula (the checker's, in floats or exactly).
StateSet = Callable[[Expr], BoolArray]


def parity_of(formula: LtlNode, states: StateSet, num_states: int,
              span: Span) -> tuple[ParityAutomaton, IntArray]:
    """The parity automaton of *formula* and each state's column of its table.

    :raises CheckError: where the automaton is too large.
    """
    try:
        found = propositions(formula)
        alphabet, column = _alphabet(letters(found.operands, states, num_states))
        automaton = parity_automaton(found.formula, len(found.operands), alphabet=alphabet)
    except AutomatonTooLarge as exc:
        raise _too_large(exc, span) from None
    except RecursionError:  # the translation recurses through the formula
        raise _too_deep(span) from None
    return automaton, column


def cosafe_of(formula: LtlNode, states: StateSet, num_states: int,
              span: Span) -> tuple[CosafeAutomaton, IntArray]:
    """The good-prefix automaton of the reward path *formula* and each state's column.

    :raises CheckError: where *formula* is not co-safe (as PRISM requires of a reward's
        path) or its automaton is too large.
    """
    try:
        found = propositions(formula)
        alphabet, column = _alphabet(letters(found.operands, states, num_states))
        automaton = cosafe_automaton(found.formula, alphabet)
    except NotCosafe:
        raise _not_cosafe(span) from None
    except AutomatonTooLarge as exc:
        raise _too_large(exc, span) from None
    except RecursionError:
        raise _too_deep(span) from None
    return automaton, column


def cosafe_refusal(path: CosafeReach) -> CheckError | None:
    """The error :func:`cosafe_of` would raise for *path* for want of co-safety (or of
    depth), found without a model; None where it has neither fault."""
    try:
        cosafe = is_syntactically_cosafe(propositions(path.formula).formula)
    except RecursionError:
        return _too_deep(path.span)
    return None if cosafe else _not_cosafe(path.span)


def _alphabet(letter: IntArray) -> tuple[list[int], IntArray]:
    """The distinct letters of the states, and each state's column among them."""
    alphabet, column = np.unique(letter, return_inverse=True)
    return [int(a) for a in alphabet], np.asarray(column, dtype=np.int64).reshape(-1)


def _not_cosafe(span: Span) -> CheckError:
    return CheckError("the path of an R operator must be co-safe LTL: with negations pushed "
                      "inward, only X, F and U over state formulas (no G, W or R)", span)


def _too_large(exc: AutomatonTooLarge, span: Span) -> CheckError:
    return CheckError(f"the LTL formula's automaton is too large: its {exc.what} passed "
                      f"{exc.limit:,} states; split the formula, or give it fewer operators "
                      "nested in each other", span)


def _too_deep(span: Span) -> CheckError:
    return CheckError("the LTL formula nests its operators too deeply to translate (a few "
                      "hundred levels at most): split it into several properties", span)
