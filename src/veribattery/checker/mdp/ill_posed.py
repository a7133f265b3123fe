"""Properties that have a value on an MDP but most likely not the question meant.

``Rmin=? [ F phi ]`` is ``Infinity`` when no strategy reaches *phi* from the initial
state at all: PRISM reports the value, but a target that cannot be reached is a
mistake in the property or the model far more often than a question, so the CLI
reports it as bad input (issue #22) after showing the value PRISM would.
"""

from __future__ import annotations

import numpy as np

from veribattery.checker.mdp.formula import _mask
from veribattery.checker.mdp.graph import ChoiceGraph, can_reach
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.operators import operator_objective
from veribattery.lang.nodes import Expr, Reach, RewardOp
from veribattery.lang.printing import expression_text

__all__ = ["unreachable_reward_target"]


def unreachable_reward_target(mdp: MDP, formula: Expr) -> str | None:
    """Why *formula* is ill-posed, or None: an ``R`` operator minimising the reward of
    ``F phi`` (``Rmin``, or ``R>=r``/``R>r``, which quantify over every strategy by the
    minimum) where no initial state has a path to *phi*."""
    if not isinstance(formula, RewardOp) or not isinstance(formula.path, Reach):
        return None
    if formula.op == "=?" and formula.direction is None:
        return None  # R=? is an error of its own (no single value on an MDP)
    if operator_objective(formula) != "min":
        return None
    target = _mask(mdp, None, formula.path.target)
    graph = ChoiceGraph.of(mdp.transitions, mdp.choice_owner)
    reaching = can_reach(graph, np.ones(mdp.num_states, dtype=bool), target)
    if reaching[mdp.initial].any():
        return None
    return (f"no strategy reaches the target {expression_text(formula.path.target)} from "
            "the initial state, so the minimum expected reward to reach it is Infinity "
            "(as PRISM reports it); check the target and the model")
