"""Negation normal form and language-preserving rewrites of an LTL formula.

The tableau (:mod:`._tableau`) wants negations on propositions only, so ``Not`` is
pushed inward by the De Morgan laws and the dualities ``!X a = X !a``,
``!(a U b) = !a R !b``, ``!(a R b) = !a U !b``. While the formula is rebuilt, smart
constructors fold constants and apply a few equivalences that are standard in LTL
translators (e.g. Somenzi and Bloem, CAV 2000; Etessami and Holzmann, CONCUR 2000):
``F F a = F a``, ``G G a = G a``, ``F G F a = G F a``, ``G F G a = F G a``,
``a U (a U b) = a U b``, ``a R (a R b) = a R b``, ``a U a = a R a = a``. Each rule is
an equivalence of LTL, so the automaton of the result recognises the same words; they
only keep the tableau's states fewer.
"""

from __future__ import annotations

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

_TRUE = Const(True)
_FALSE = Const(False)


def normal_form(f: LtlFormula) -> LtlFormula:
    """``f`` in negation normal form (``Not`` only around ``Prop``), simplified."""
    return _positive(f)


def _positive(f: LtlFormula) -> LtlFormula:
    match f:
        case Prop() | Const():
            return f
        case Not(operand):
            return _negative(operand)
        case And(left, right):
            return _and(_positive(left), _positive(right))
        case Or(left, right):
            return _or(_positive(left), _positive(right))
        case Next(operand):
            return _next(_positive(operand))
        case Until(left, right):
            return _until(_positive(left), _positive(right))
        case Release(left, right):
            return _release(_positive(left), _positive(right))
    raise TypeError(f"not an LTL formula: {f!r}")


def _negative(f: LtlFormula) -> LtlFormula:
    """The normal form of ``Not(f)``."""
    match f:
        case Prop():
            return Not(f)
        case Const(value):
            return Const(not value)
        case Not(operand):
            return _positive(operand)
        case And(left, right):
            return _or(_negative(left), _negative(right))
        case Or(left, right):
            return _and(_negative(left), _negative(right))
        case Next(operand):
            return _next(_negative(operand))
        case Until(left, right):
            return _release(_negative(left), _negative(right))
        case Release(left, right):
            return _until(_negative(left), _negative(right))
    raise TypeError(f"not an LTL formula: {f!r}")


def _complementary(a: LtlFormula, b: LtlFormula) -> bool:
    """Whether ``a`` and ``b`` are a literal and its negation."""
    return (isinstance(a, Not) and a.operand == b) or (isinstance(b, Not) and b.operand == a)


def _and(a: LtlFormula, b: LtlFormula) -> LtlFormula:
    if a == _FALSE or b == _FALSE or _complementary(a, b):
        return _FALSE
    if a == _TRUE:
        return b
    if b == _TRUE or a == b:
        return a
    return And(a, b)


def _or(a: LtlFormula, b: LtlFormula) -> LtlFormula:
    if a == _TRUE or b == _TRUE or _complementary(a, b):
        return _TRUE
    if a == _FALSE:
        return b
    if b == _FALSE or a == b:
        return a
    return Or(a, b)


def _next(a: LtlFormula) -> LtlFormula:
    # X of a constant is that constant: every position has a successor.
    return a if isinstance(a, Const) else Next(a)


def _is_globally_eventually(f: LtlFormula) -> bool:
    return (isinstance(f, Release) and f.left == _FALSE and isinstance(f.right, Until)
            and f.right.left == _TRUE)


def _is_eventually_globally(f: LtlFormula) -> bool:
    return (isinstance(f, Until) and f.left == _TRUE and isinstance(f.right, Release)
            and f.right.left == _FALSE)


def _until(a: LtlFormula, b: LtlFormula) -> LtlFormula:
    if isinstance(b, Const) or a in (_FALSE, b):
        return b  # a U true = true, a U false = false, false U b = b, b U b = b
    if isinstance(b, Until) and b.left == a:
        return b  # a U (a U b) = a U b; with a = true, F F b = F b
    if a == _TRUE and _is_globally_eventually(b):
        return b  # F G F b = G F b: G F b does not depend on a finite prefix
    return Until(a, b)


def _release(a: LtlFormula, b: LtlFormula) -> LtlFormula:
    if isinstance(b, Const) or a in (_TRUE, b):
        return b  # a R true = true, a R false = false, true R b = b, b R b = b
    if isinstance(b, Release) and b.left == a:
        return b  # a R (a R b) = a R b; with a = false, G G b = G b
    if a == _FALSE and _is_eventually_globally(b):
        return b  # G F G b = F G b
    return Release(a, b)
