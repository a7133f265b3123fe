"""What a property's ``P``/``R``/``T`` operator names on an MDP: the objective it
optimises and the reward structure it reads."""

from __future__ import annotations

import numpy as np

from veribattery.checker.formula.leaves import require_nonnegative_rewards
from veribattery.checker.mdp.model import MDP, MdpRewards
from veribattery.checker.mdp.system import Objective
from veribattery.errors import CheckError
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import Expr, Multi, ProbOp, RewardBounded, RewardOp
from veribattery.lang.property_rules import STEPS_REWARD

__all__ = ["CONDITIONAL_ON_MDP", "operator_objective", "require_objectives",
           "reward_structure"]

#: Why Storm's conditional formulas are refused on MDPs (float and exact).
CONDITIONAL_ON_MDP = ("conditional probabilities (Storm's 'path || F condition') are not "
                      "supported on MDPs: check the DTMC a strategy induces instead "
                      "(--export-induced)")


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


def require_objectives(formula: Expr) -> None:
    """Refuse, before any state is built, an operator with no objective on an MDP
    (``P=?``, :func:`operator_objective`'s error): the check would refuse it only after
    the build. A ``multi(...)`` query is left to its own checks.

    :raises CheckError: at the first such operator.
    """
    nodes = list(walk(formula))
    if any(type(node) is Multi for node in nodes):
        return
    for node in nodes:
        if type(node) in (ProbOp, RewardOp):
            operator_objective(node)
