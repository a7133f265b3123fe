"""The optimal strategy of a property: the memoryless deterministic strategy that
attains a ``Pmin``/``Pmax``/``Rmin``/``Rmax`` over an unbounded path.

Only these have one strategy that is optimal from every state at once. A step-bounded
objective (``F<=k``, ``X``, ``C<=k``, ``I=k``) needs the number of steps taken
(:class:`~veribattery.checker.mdp.StepStrategy`), and a formula with no P or R operator
at its top has no strategy, and a ``multi(...)`` answer needs randomisation and memory
(:mod:`~veribattery.checker.mdp.multi_strategy` builds that one): all are refused here
with :class:`NoStrategyError`.
"""

from __future__ import annotations

from veribattery.checker.mdp.formula import _direction, _mask, _opposite
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.result import MdpResult
from veribattery.checker.mdp.rewards import reach_reward, total_reward
from veribattery.checker.mdp.strategy import Strategy
from veribattery.checker.mdp.system import Objective
from veribattery.errors import CheckError
from veribattery.lang.nodes import (
    Eventually,
    Expr,
    Globally,
    Multi,
    PathFormula,
    ProbOp,
    Reach,
    Release,
    RewardOp,
    Total,
    Until,
    WeakUntil,
)

__all__ = ["NoStrategyError", "property_strategy"]


class NoStrategyError(CheckError):
    """The property has no memoryless optimal strategy to show (the message says why)."""


def property_strategy(mdp: MDP, formula: Expr) -> Strategy:
    """The optimal strategy of *formula*, a ``P``/``R`` operator at the top (``P~p``
    quantifies over every strategy: its strategy is the one of the extreme it reads).

    :raises NoStrategyError: a step-bounded path, or no P/R operator at the top.
    :raises CheckError: as checking the property would (an unknown reward structure, ...).
    """
    match formula:
        case ProbOp(path=path):
            result = _path_result(mdp, path, _direction(formula))
        case RewardOp():
            result = _reward_result(mdp, formula, _direction(formula))
        case Multi():
            raise NoStrategyError("no memoryless deterministic strategy: a multi-objective "
                                  "answer is attained by a randomised strategy with memory "
                                  "(see multi_strategy)", formula.span)
        case _:
            raise NoStrategyError("no strategy: the property has no P or R operator at its "
                                  "top (it is a filter, a comparison, arithmetic or a "
                                  "constant)", formula.span)
    assert isinstance(result.strategy, Strategy)
    return result.strategy


def _path_result(mdp: MDP, path: PathFormula, objective: Objective) -> MdpResult:
    """The kernel result of an unbounded path; the dual paths (``G``, ``W``, ``R``) take
    the strategy of their complement's opposite objective, which attains theirs."""
    if getattr(path, "bound", None) is not None or not isinstance(
            path, Eventually | Until | Globally | WeakUntil | Release):
        raise _step_bounded(path)
    match path:
        case Eventually(operand=operand):
            return reach_probability(mdp, _mask(mdp, None, operand), objective=objective)
        case Until(left=left, right=right):
            return reach_probability(mdp, _mask(mdp, None, right), objective=objective,
                                     remain=_mask(mdp, None, left))
        case Globally(operand=operand):
            return reach_probability(mdp, ~_mask(mdp, None, operand),
                                     objective=_opposite(objective))
        case WeakUntil(left=left, right=right):
            a, b = _mask(mdp, None, left), _mask(mdp, None, right)
            return reach_probability(mdp, ~a & ~b, objective=_opposite(objective),
                                     remain=a & ~b)
    assert isinstance(path, Release)
    a, b = _mask(mdp, None, path.left), _mask(mdp, None, path.right)
    return reach_probability(mdp, ~b, objective=_opposite(objective), remain=~a)


def _reward_result(mdp: MDP, op: RewardOp, objective: Objective) -> MdpResult:
    try:
        structure = mdp.reward(op.reward)
    except (KeyError, IndexError):
        raise CheckError(f"unknown reward structure {op.reward!r}", op.span) from None
    match op.path:
        case Reach(target=target):
            return reach_reward(mdp, structure.per_choice(mdp), _mask(mdp, None, target),
                                objective=objective)
        case Total():
            return total_reward(mdp, structure.per_choice(mdp), objective=objective)
    raise _step_bounded(op.path)


def _step_bounded(path: object) -> NoStrategyError:
    span = getattr(path, "span", None)
    return NoStrategyError(
        "no memoryless strategy: the objective is step-bounded (X, a bounded F/U/G/W/R, "
        "C<=k or I=k), so the optimal choice depends on the steps left; such strategies "
        "are not exported", span)
