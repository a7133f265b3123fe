"""The LTL syntax tree the automata are built from, over atomic propositions 0..k-1.

The core is eight frozen node classes (:class:`Prop`, :class:`Const`, :class:`Not`,
:class:`And`, :class:`Or`, :class:`Next`, :class:`Until`, :class:`Release`); the usual
derived operators (F, G, W, =>, <=>) are functions that build core nodes, so every
later stage -- normal form, tableau, determinisation -- handles eight cases only.

Semantics, on an infinite word ``w0 w1 ...`` of letters (bit ``i`` of a letter set iff
``Prop(i)`` holds there), at position ``j``: ``Next(a)`` iff ``a`` at ``j + 1``;
``Until(a, b)`` iff ``b`` at some ``m >= j`` and ``a`` at every ``j <= i < m``;
``Release(a, b)`` iff ``Not(Until(Not a, Not b))``, i.e. ``b`` holds up to and including
the first position where ``a`` holds, or forever.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Prop:
    """Atomic proposition number ``index`` (bit ``index`` of the letter)."""

    index: int


@dataclass(frozen=True, slots=True)
class Const:
    """``true`` or ``false``."""

    value: bool


@dataclass(frozen=True, slots=True)
class Not:
    """Negation."""

    operand: LtlFormula


@dataclass(frozen=True, slots=True)
class And:
    """Conjunction."""

    left: LtlFormula
    right: LtlFormula


@dataclass(frozen=True, slots=True)
class Or:
    """Disjunction."""

    left: LtlFormula
    right: LtlFormula


@dataclass(frozen=True, slots=True)
class Next:
    """``X operand``: the operand holds at the next position."""

    operand: LtlFormula


@dataclass(frozen=True, slots=True)
class Until:
    """``left U right`` (strong until: ``right`` must eventually hold)."""

    left: LtlFormula
    right: LtlFormula


@dataclass(frozen=True, slots=True)
class Release:
    """``left R right``, the dual of until: ``!(!left U !right)``."""

    left: LtlFormula
    right: LtlFormula


LtlFormula = Prop | Const | Not | And | Or | Next | Until | Release


def eventually(f: LtlFormula) -> LtlFormula:
    """``F f`` = ``true U f``."""
    return Until(Const(True), f)


def globally(f: LtlFormula) -> LtlFormula:
    """``G f`` = ``false R f``."""
    return Release(Const(False), f)


def weak_until(a: LtlFormula, b: LtlFormula) -> LtlFormula:
    """``a W b`` = ``b R (a | b)``: ``a`` until ``b``, or ``a`` forever.

    This form (rather than ``(a U b) | G a``) repeats no subformula, which keeps the
    tableau's states fewer.
    """
    return Release(b, Or(a, b))


def implies(a: LtlFormula, b: LtlFormula) -> LtlFormula:
    """``a => b`` = ``!a | b``."""
    return Or(Not(a), b)


def iff(a: LtlFormula, b: LtlFormula) -> LtlFormula:
    """``a <=> b`` = ``(a & b) | (!a & !b)``."""
    return Or(And(a, b), And(Not(a), Not(b)))


def is_syntactically_cosafe(f: LtlFormula) -> bool:
    """Whether ``f``'s negation normal form uses only literals, constants, and, or, X, U.

    This is PRISM's syntactic rule for LTL under a reward operator: such a formula's
    every satisfying word has a finite good prefix. The rule is syntactic on purpose
    (no simplification first): ``true R a`` is rejected although it means ``a``.
    Negations are pushed inward implicitly by tracking the polarity: a negated until
    becomes a release and a negated release an until.
    """
    return _cosafe(f, positive=True)


def _cosafe(f: LtlFormula, *, positive: bool) -> bool:
    match f:
        case Prop() | Const():
            return True
        case Not(operand):
            return _cosafe(operand, positive=not positive)
        case And(left, right) | Or(left, right):
            return _cosafe(left, positive=positive) and _cosafe(right, positive=positive)
        case Next(operand):
            return _cosafe(operand, positive=positive)
        case Until(left, right):
            return positive and _cosafe(left, positive=True) and _cosafe(right, positive=True)
        case Release(left, right):
            return (not positive and _cosafe(left, positive=False)
                    and _cosafe(right, positive=False))
    raise TypeError(f"not an LTL formula: {f!r}")
