"""An independent LTL semantics on lasso words, and random formulas and words for tests.

:func:`holds` evaluates a formula on the ultimately periodic word ``u v v v ...`` at
position 0 straight from the definitions, with no automaton: the word has only
``|u| + |v|`` distinct suffixes, so each subformula is a vector of truth values over
these positions, where position ``|u| + |v| - 1`` is followed by ``|u|``. ``a U b`` is
the least fixpoint of ``S = b | (a & X S)`` and ``a R b`` the greatest fixpoint of
``S = b & (a | X S)``, both reached by plain iteration from all-false / all-true.
"""

from __future__ import annotations

import random
from collections.abc import Sequence

from veribattery.checker.automata import (
    And,
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
    weak_until,
)


def holds(f: LtlFormula, prefix: Sequence[int], cycle: Sequence[int]) -> bool:
    """Whether ``prefix cycle^omega`` satisfies ``f`` at position 0."""
    word = [*prefix, *cycle]
    size = len(word)
    after = [*range(1, size), len(prefix)]

    def value(g: LtlFormula) -> list[bool]:
        match g:
            case Prop(index):
                return [bool(letter >> index & 1) for letter in word]
            case Const(truth):
                return [truth] * size
            case Not(operand):
                return [not x for x in value(operand)]
            case And(left, right):
                return [x and y for x, y in zip(value(left), value(right), strict=True)]
            case Or(left, right):
                return [x or y for x, y in zip(value(left), value(right), strict=True)]
            case Next(operand):
                inner = value(operand)
                return [inner[after[i]] for i in range(size)]
            case Until(left, right):
                return _fixpoint(value(left), value(right), after, least=True)
            case Release(left, right):
                return _fixpoint(value(left), value(right), after, least=False)
        raise TypeError(g)

    return value(f)[0]


def _fixpoint(a: list[bool], b: list[bool], after: list[int], *, least: bool) -> list[bool]:
    current = [not least] * len(a)
    while True:
        if least:
            new = [b[i] or (a[i] and current[after[i]]) for i in range(len(a))]
        else:
            new = [b[i] and (a[i] or current[after[i]]) for i in range(len(a))]
        if new == current:
            return current
        current = new


def random_formula(rng: random.Random, propositions: int, depth: int) -> LtlFormula:
    """A random formula of at most ``depth`` operator levels, every operator possible."""
    if depth == 0 or rng.random() < 0.15:
        if rng.random() < 0.12:
            return Const(rng.random() < 0.5)
        return Prop(rng.randrange(propositions))
    unary = [Not, Next, eventually, globally]
    binary = [And, Or, Until, Release, weak_until, implies, iff]
    if rng.random() < 0.45:
        return rng.choice(unary)(random_formula(rng, propositions, depth - 1))
    op = rng.choice(binary)
    return op(random_formula(rng, propositions, depth - 1),
              random_formula(rng, propositions, depth - 1))


def random_lasso(rng: random.Random, propositions: int) -> tuple[list[int], list[int]]:
    """A random word ``u v^omega`` with ``|u|`` in 0..4 and ``|v|`` in 1..4."""
    letters = 1 << propositions
    prefix = [rng.randrange(letters) for _ in range(rng.randrange(5))]
    cycle = [rng.randrange(letters) for _ in range(rng.randrange(1, 5))]
    return prefix, cycle
