"""LTL formulas to deterministic parity automata, for the product with DTMCs and MDPs.

:mod:`.formula` holds the LTL syntax; :mod:`.parity` the automata and their
construction (tableau, Safra-Piterman determinisation, minimisation); :mod:`.cosafe` the
automaton of a co-safe formula's good prefixes, as PRISM reads a reward's path.
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
    eventually,
    globally,
    iff,
    implies,
    is_syntactically_cosafe,
    weak_until,
)
from veribattery.checker.automata.parity import (
    AutomatonTooLarge,
    ParityAutomaton,
    parity_automaton,
)

__all__ = [
    "And", "AutomatonTooLarge", "Const", "LtlFormula", "Next", "Not", "Or", "ParityAutomaton",
    "Prop", "Release", "Until", "eventually", "globally", "iff", "implies",
    "is_syntactically_cosafe", "parity_automaton", "weak_until",
]
