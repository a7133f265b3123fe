"""What a property's ``P``/``R``/``T`` operator names on an MDP: the objective it
optimises and the reward structure it reads."""

from __future__ import annotations

import numpy as np

from veribattery.checker.formula.leaves import require_nonnegative_rewards
from veribattery.checker.ltl.cosafety import require_cosafe
from veribattery.checker.mdp.model import MDP, MdpRewards
from veribattery.checker.mdp.system import Objective
from veribattery.errors import CheckError
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    Conditional,
    ConditionalReach,
    Expr,
    LongRun,
    Multi,
    ProbOp,
    RewardBounded,
    RewardOp,
    SteadyOp,
)
from veribattery.lang.property_rules import STEPS_REWARD

__all__ = ["CONDITIONAL_ON_MDP", "LONG_RUN_ON_MDP", "operator_objective", "require_checkable",
           "reward_structure", "unsupported_on_mdp"]

#: Why Storm's conditional formulas are refused on MDPs (float and exact).
CONDITIONAL_ON_MDP = ("conditional probabilities (Storm's 'path || F condition') are not "
                      "supported on MDPs: check the DTMC a strategy induces instead "
                      "(--export-induced)")
#: Why long-run operators are refused on MDPs (PRISM refuses them there too).
LONG_RUN_ON_MDP = ("long-run operators (S, and R [ S ]) are not supported on MDPs: check "
                   "the DTMC a strategy induces instead (--export-induced)")


def reward_structure(mdp: MDP, op: RewardOp | RewardBounded) -> MdpRewards:
    """The reward structure *op* (an R operator or a reward bound) reads; Storm's
    ``Tmin``/``Tmax`` count each step as 1.

    :raises CheckError: the model has no such structure, or it has a negative reward.
    """
    if op.reward == STEPS_REWARD:
        return MdpRewards(None, np.ones(mdp.num_states), np.zeros(mdp.num_choices))
    try:
        structure = mdp.reward(op.reward)
    except (KeyError, IndexError):
        raise CheckError(f"unknown reward structure {op.reward!r}", op.span) from None
    require_nonnegative_rewards(structure.name, (structure.state, structure.choice), op)
    return structure


def operator_objective(op: ProbOp | RewardOp) -> Objective:
    """The objective of an operator: its own ``min``/``max``, else (``P~p``) the one
    that quantifies over every strategy; ``P=?``/``R=?``/``T=?`` have none on an MDP."""
    if op.direction is not None:
        return op.direction
    if op.op == "=?":
        name = "P" if isinstance(op, ProbOp) else "T" if op.reward == STEPS_REWARD else "R"
        raise CheckError(f"{name}=? on an MDP has no single value: use {name}min=? or "
                         f"{name}max=?", op.span)
    return "max" if op.op in ("<", "<=") else "min"


def unsupported_on_mdp(formula: Expr) -> CheckError | None:
    """The refusal of the first part of *formula* that the MDP engine does not check
    (long-run operators, Storm's conditional formulas), or None."""
    for node in walk(formula):
        kind = type(node)
        if kind is SteadyOp or (kind is RewardOp and type(node.path) is LongRun):
            return CheckError(LONG_RUN_ON_MDP, node.span)
        if kind is Conditional or kind is ConditionalReach:
            return CheckError(CONDITIONAL_ON_MDP, node.span)
    return None


def require_checkable(formula: Expr) -> None:
    """Refuse, before any state is built, what the check of *formula* on an MDP would
    refuse only after the build: a part the engine does not check
    (:func:`unsupported_on_mdp`), an operator with no objective (``P=?``,
    :func:`operator_objective`'s error; a ``multi(...)`` query's objectives are left to
    its own checks), a reward path that is not co-safe LTL.

    :raises CheckError: at the first such part.
    """
    refusal = unsupported_on_mdp(formula)
    if refusal is not None:
        raise refusal
    nodes = list(walk(formula))
    if not any(type(node) is Multi for node in nodes):
        for node in nodes:
            if type(node) in (ProbOp, RewardOp):
                operator_objective(node)
    require_cosafe(formula)
