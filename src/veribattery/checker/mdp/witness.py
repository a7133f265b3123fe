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

from veribattery.checker.mdp.formula import _mask, _opposite
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.operators import (
    CONDITIONAL_ON_MDP,
    operator_objective,
    reward_structure,
)
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.result import MdpResult
from veribattery.checker.mdp.rewards import reach_reward, total_reward
from veribattery.checker.mdp.strategy import Strategy
from veribattery.checker.mdp.system import Objective
from veribattery.errors import CheckError
from veribattery.lang.nodes import (
    Conditional,
    ConditionalReach,
    CosafeReach,
    Cumulative,
    Eventually,
    Expr,
    Globally,
    Instantaneous,
    LtlPath,
    Multi,
    Next,
    PathFormula,
    ProbOp,
    Reach,
    Release,
    RewardBounded,
    RewardOp,
    Total,
    Until,
    WeakUntil,
)

__all__ = ["NoStrategyError", "property_strategy", "strategy_refusal"]


class NoStrategyError(CheckError):
    """The property has no memoryless optimal strategy to show (the message says why)."""


def strategy_refusal(formula: Expr) -> NoStrategyError | None:
    """Why *formula* has no strategy to export as far as its shape tells, before any
    model is built (``--export-strategy`` is refused before the work starts), or None
    when it may have one (a ``multi(...)`` answer can still be false or unattained).

    No P or R operator at the top, a step-bounded path (``X``, a bounded
    ``F``/``U``/``G``/``W``/``R``, ``C<=k``, ``I=k``), or a ``C<=k`` objective in
    ``multi(...)``.
    """
    match formula:
        case ProbOp(path=path):
            unbounded = getattr(path, "bound", None) is None and isinstance(
                path, Eventually | Until | Globally | WeakUntil | Release)
            return None if unbounded else _no_memoryless(path)
        case RewardOp(path=path):
            return None if isinstance(path, Reach | Total) else _no_memoryless(path)
        case Multi(objectives=objectives):
            ltl = [op for op in objectives
                   if isinstance(op, ProbOp) and isinstance(op.path, LtlPath)]
            if ltl:
                return NoStrategyError(
                    "no strategy exported: an LTL objective in multi(...) needs the "
                    "automata's states as memory; only F, G, state-formula and C objectives "
                    "have exported multi-objective strategies", ltl[0].span)
            counting = [op for op in objectives
                        if isinstance(op, RewardOp) and isinstance(op.path, Cumulative)]
            return None if not counting else NoStrategyError(
                "no strategy exported: a C<=k objective in multi(...) needs a strategy that "
                "also counts the steps taken; only F, G, state-formula and C objectives "
                "have exported multi-objective strategies", counting[0].span)
    return NoStrategyError("no strategy: the property has no P or R operator at its top (it "
                           "is a filter, a comparison, arithmetic or a constant)", formula.span)


def property_strategy(mdp: MDP, formula: Expr) -> Strategy:
    """The optimal strategy of *formula*, a ``P``/``R`` operator at the top (``P~p``
    quantifies over every strategy: its strategy is the one of the extreme it reads).

    :raises NoStrategyError: a step-bounded path, or no P/R operator at the top.
    :raises CheckError: as checking the property would (an unknown reward structure, ...).
    """
    refusal = strategy_refusal(formula)
    if refusal is not None:
        raise refusal
    match formula:
        case ProbOp(path=path):
            result = _path_result(mdp, path, operator_objective(formula))
        case RewardOp():
            result = _reward_result(mdp, formula, operator_objective(formula))
        case _:
            raise NoStrategyError("no memoryless deterministic strategy: a multi-objective "
                                  "answer is attained by a randomised strategy with memory "
                                  "(see multi_strategy)", formula.span)
    assert isinstance(result.strategy, Strategy)
    return result.strategy


def _path_result(mdp: MDP, path: PathFormula, objective: Objective) -> MdpResult:
    """The kernel result of an unbounded path; the dual paths (``G``, ``W``, ``R``) take
    the strategy of their complement's opposite objective, which attains theirs."""
    if getattr(path, "bound", None) is not None or not isinstance(
            path, Eventually | Until | Globally | WeakUntil | Release):
        raise _no_memoryless(path)
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
    structure = reward_structure(mdp, op)
    match op.path:
        case Reach(target=target):
            return reach_reward(mdp, structure.per_choice(mdp), _mask(mdp, None, target),
                                objective=objective)
        case Total():
            return total_reward(mdp, structure.per_choice(mdp), objective=objective)
    raise _no_memoryless(op.path)


def _no_memoryless(path: object) -> NoStrategyError:
    """Why an operator over *path* (not an unbounded F/U/G/W/R, R[F], R[C]) has no
    memoryless strategy: mostly a step or reward bound."""
    span = getattr(path, "span", None)
    if isinstance(path, Conditional | ConditionalReach):
        return NoStrategyError(f"no strategy: {CONDITIONAL_ON_MDP}", span)
    if isinstance(path, LtlPath | CosafeReach):
        return NoStrategyError("no memoryless strategy: an optimal strategy for LTL needs the "
                               "automaton's state as memory; such strategies are not exported",
                               span)
    if not (isinstance(path, Next | Cumulative | Instantaneous | RewardBounded)
            or getattr(path, "bound", None) is not None):
        return NoStrategyError("no memoryless strategy is exported for this path: only for "
                               "unbounded F, U, G, W, R, R[F] and R[C]", span)
    if isinstance(path, RewardBounded):
        return NoStrategyError(
            "no memoryless strategy: the objective is reward-bounded (F{\"r\"}<=T), so "
            "the optimal choice depends on the reward budget left; such strategies are not "
            "exported", span)
    return NoStrategyError(
        "no memoryless strategy: the objective is step-bounded (X, a bounded F/U/G/W/R, "
        "C<=k or I=k), so the optimal choice depends on the steps left; such strategies "
        "are not exported", span)
