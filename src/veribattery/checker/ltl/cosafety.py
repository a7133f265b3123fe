"""The co-safety a reward's LTL path needs, checked before any state is built."""

from __future__ import annotations

from veribattery.lang.expressions import walk
from veribattery.lang.nodes import CosafeReach, Expr

__all__ = ["require_cosafe"]


def require_cosafe(formula: Expr) -> None:
    """Refuse an R operator of *formula* whose path is not co-safe LTL, before the model
    is built (the check would refuse it only then, after the build's wait).

    :raises CheckError: at the first such path.
    """
    for node in walk(formula):
        if type(node) is CosafeReach:
            # The automata package only where an LTL reward path is met (it costs ~20 ms).
            from veribattery.checker.ltl.automaton import cosafe_refusal

            refusal = cosafe_refusal(node)
            if refusal is not None:
                raise refusal
