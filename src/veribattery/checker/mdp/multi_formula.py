"""``multi(...)`` properties on an MDP: PRISM's multi-objective queries, read into the
objectives of :mod:`~veribattery.checker.mdp.multi` and answered at the initial state.

Objectives: ``P [ F phi ]``, ``P [ G phi ]`` (``1 - P [ F !phi ]``), ``P [ phi ]``
(a state formula: 1 if the initial state satisfies it, else 0), ``R{"r"} [ C ]``
and ``R{"r"} [ C<=k ]`` (on the MDP unfolded with a step counter,
:mod:`~veribattery.checker.mdp.multi_steps`). As in PRISM, strict bounds are read
as non-strict, ``Pmin=?``/``Rmin=?`` minimise over the strategies that meet the
other objectives, and only strategies whose total rewards are finite count.

A numerical query of the shape ``multi(R{"r"}min=? [ C ], P>=p [ F phi ])`` (one
total reward minimised, one reachability bounded from below) is answered from the
two-objective Pareto front by weighted sums (:mod:`~veribattery.checker.mdp.multi_front`):
a certified interval, ``certified=True``. Every other shape is a linear programme,
solved in floating point by HiGHS (``docs/mdp-numerics.md``):
a numerical query reports its optimum with an error *estimate* of
:data:`~veribattery.checker.mdp.multi.LP_TOLERANCE` (relative, absolute below 1)
and ``certified=False``. An achievability query is decided from the best margin
by which a strategy meets every bound: true and certified when the programme's
vertex, solved again exactly, meets them all; otherwise true or false (not
certified) when the margin is beyond the tolerance, and undecided -- an error
naming the property, never a guess -- within it. A numerical query whose other
objectives no strategy meets is an error too (PRISM prints NaN).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from veribattery._types import BoolArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.formula.filters import FilterOutcome
from veribattery.checker.formula.intervals import Undecided
from veribattery.checker.kernels.reward_layers import PRODUCT_LIMIT
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.multi import (
    LP_TOLERANCE,
    Constraint,
    Quantity,
    Reach,
    Total,
    multi_margin,
    multi_optimum,
)
from veribattery.checker.mdp.multi_front import FrontSearch
from veribattery.checker.mdp.multi_ltl import has_ltl, stopped_query
from veribattery.checker.mdp.multi_steps import SteppedMdp
from veribattery.checker.mdp.operators import reward_structure
from veribattery.checker.mdp.system import Objective
from veribattery.errors import CheckError, UndefinedResult
from veribattery.lang.evaluate import evaluate
from veribattery.lang.nodes import (
    BoolLit,
    Cumulative,
    Eventually,
    Expr,
    Globally,
    Multi,
    ProbOp,
    RewardOp,
    Until,
)
from veribattery.lang.nodes import (
    Total as TotalPath,
)

__all__ = ["StateMask", "multi_answer"]

#: Per-state mask of a state formula (the MDP checker's own evaluation).
StateMask = Callable[[Expr], BoolArray]


@dataclass(frozen=True, slots=True)
class _Goal:
    """One objective as ``offset + sign * quantity`` (``P [ G phi ]`` is
    ``1 - P [ F !phi ]``), with the operator it comes from."""

    op: ProbOp | RewardOp
    quantity: Quantity
    sign: Literal[1, -1] = 1
    offset: float = 0.0


def multi_answer(mdp: MDP, query: Multi, mask: StateMask) -> FilterOutcome:
    """The answer to ``multi(...)`` at the single initial state: a boolean for an
    achievability query, else the optimum of its ``=?`` objective.

    :raises CheckError: an objective outside the supported ones, several initial
        states, no strategy meeting the bounds of a numerical query, or an
        achievability query too close to call.
    """
    if mdp.initial.size != 1:
        raise CheckError("multi(...) needs a single initial state", query.span)
    if has_ltl(query):  # LTL objectives: reachability of stop states in a product
        goals, model = _goals(*stopped_query(mdp, query, mask))
    else:
        goals, model = _goals(mdp, query, mask)
    constraints = [_constraint(goal) for goal in goals if goal.op.op != "=?"]
    queried = [goal for goal in goals if goal.op.op == "=?"]
    if queried:
        return _numerical(mdp, model, queried[0], constraints, query)
    return _achievability(mdp, model, constraints, query)


def _goals(mdp: MDP, query: Multi, mask: StateMask) -> tuple[list[_Goal], MDP]:
    """The objectives, and the MDP their quantities live on (unfolded with a step
    counter when one of them is step-bounded)."""
    stepped = _unfolded(mdp, query)
    goals = [_goal(mdp, stepped, op, mask) for op in _operators(query)]
    return goals, mdp if stepped is None else stepped.mdp


def _unfolded(mdp: MDP, query: Multi) -> SteppedMdp | None:
    """*mdp* unfolded up to the largest step bound of *query* (None: it has none).

    :raises CheckError: the unfolded MDP would pass the products' size limit.
    """
    bounds = [(steps, op) for op in _operators(query) if (steps := _steps(op)) is not None]
    if not bounds:
        return None
    steps, op = max(bounds, key=lambda pair: pair[0])
    size = (steps + 1) * mdp.transitions.nnz
    if size > PRODUCT_LIMIT:
        assert isinstance(op.path, Cumulative)
        raise CheckError(f"a step bound of {steps} unfolds the model into {size:,} "
                         f"transitions (at most {PRODUCT_LIMIT:,}): use a smaller bound",
                         op.path.bound.span)
    return SteppedMdp.of(mdp, steps)


def _operators(query: Multi) -> list[ProbOp | RewardOp]:
    """The objectives (the type checker made sure each is a P or R operator)."""
    return [op for op in query.objectives if isinstance(op, ProbOp | RewardOp)]


def _steps(op: ProbOp | RewardOp) -> int | None:
    """The step bound of ``R [ C<=k ]``, None for every other objective."""
    if isinstance(op, RewardOp) and isinstance(op.path, Cumulative):
        return int(evaluate(op.path.bound, {}))
    return None


def _goal(mdp: MDP, stepped: SteppedMdp | None, op: ProbOp | RewardOp,
          mask: StateMask) -> _Goal:
    if isinstance(op, RewardOp):
        return _reward_goal(mdp, stepped, op)
    lift = (lambda states: states) if stepped is None else stepped.states
    match op.path:
        case Eventually(operand=operand, bound=None) | Until(
                left=BoolLit(value=True), right=operand, bound=None):
            return _Goal(op, Reach(lift(mask(operand))))
        case Globally(operand=operand, bound=None):
            return _Goal(op, Reach(lift(~mask(operand))), -1, 1.0)
        case Until(left=BoolLit(value=False), right=operand, bound=None):  # P [ phi ]
            return _Goal(op, Reach(lift(mask(operand) & mdp.initial_mask)))
    raise CheckError("multi(...) takes P objectives over F phi, G phi, a state formula or, "
                     "alongside LTL, any unbounded path (no time bounds)", op.path.span)


def _reward_goal(mdp: MDP, stepped: SteppedMdp | None, op: RewardOp) -> _Goal:
    """A reward objective: its structure's rewards per choice (on the unfolded MDP)."""
    per_choice = reward_structure(mdp, op).per_choice(mdp)  # (which refuses negative ones)
    if isinstance(op.path, TotalPath):
        lifted = per_choice if stepped is None else stepped.rewards(per_choice)
        return _Goal(op, Total(lifted))
    if isinstance(op.path, Cumulative):
        assert stepped is not None  # a step bound makes the unfolding
        return _Goal(op, Total(stepped.rewards(per_choice, _steps(op))))
    raise CheckError("multi(...) takes R objectives over C or C<=k", op.path.span)


def _constraint(goal: _Goal) -> Constraint:
    """``offset + sign * q ~ bound`` as ``q ~' bound'`` (strict read as non-strict)."""
    assert goal.op.bound is not None
    bound = float(evaluate(goal.op.bound, {}))
    at_least = goal.op.op in (">=", ">")
    if goal.sign < 0:
        at_least = not at_least
    return Constraint(goal.quantity, ">=" if at_least else "<=",
                      (bound - goal.offset) / goal.sign)


def _numerical(mdp: MDP, model: MDP, goal: _Goal, constraints: list[Constraint],
               query: Multi) -> FilterOutcome:
    """The optimum of the ``=?`` objective, with an error estimate, not certified."""
    direction = goal.op.direction
    if direction is None:
        name = "P" if isinstance(goal.op, ProbOp) else "R"
        raise CheckError(f"the =? objective of multi(...) needs a direction: {name}min=? "
                         f"or {name}max=?", goal.op.span)
    objective = _towards(direction, goal.sign)
    front = _front_answer(mdp, model, goal, objective, constraints, query)
    if front is not None:
        return front
    found = multi_optimum(model, goal.quantity, objective, constraints)
    if not found.achievable or found.value is None:
        raise _no_optimum(query)
    value = goal.offset + goal.sign * found.value
    error = LP_TOLERANCE * max(1.0, abs(value)) if np.isfinite(value) else 0.0
    values = _at_initial(mdp, value, error)
    return FilterOutcome(value, values, interval=(value - error, value + error),
                         precise=False, certified=False)


def _no_optimum(query: Multi) -> UndefinedResult:
    """No strategy meets the bounded objectives (finite total rewards among them)."""
    rewards = any(isinstance(objective, RewardOp) for objective in query.objectives)
    return UndefinedResult("multi(...) has no strategy that meets its bounded objectives"
                           + (" with finite total rewards" if rewards else "")
                           + ", so the =? objective has no optimum (NaN, as PRISM reports it)",
                           query.span)


def _front_answer(mdp: MDP, model: MDP, goal: _Goal, objective: Objective,
                  constraints: list[Constraint], query: Multi) -> FilterOutcome | None:
    """The certified answer of ``R min=? [ C ]`` under one ``P >= p`` constraint, or
    None for any other shape (or where the front leaves it undecided: the programme
    answers then)."""
    if not (isinstance(goal.quantity, Total) and objective == "min" and goal.sign > 0
            and len(constraints) == 1 and isinstance(constraints[0].quantity, Reach)
            and constraints[0].relation == ">="):
        return None
    search = FrontSearch(model, constraints[0].quantity, goal.quantity)
    answer = search.least_total_at(constraints[0].bound)
    if answer is None:
        return None
    if not answer.achievable or answer.total is None:
        raise _no_optimum(query)
    total = answer.total
    point = np.full(mdp.num_states, np.nan)
    lower, upper = point.copy(), point.copy()
    point[mdp.initial], lower[mdp.initial], upper[mdp.initial] = (
        total.value, total.lower, total.upper)
    values = Bounds(point, lower, upper)
    return FilterOutcome(total.value, values, interval=(total.lower, total.upper),
                         precise=bool(values.at(mdp.initial).precise_states().all()),
                         certified=True)


def _towards(direction: Objective, sign: int) -> Objective:
    """Optimising ``offset + sign * q`` optimises *q* the same way, or the other way."""
    if sign > 0:
        return direction
    return "min" if direction == "max" else "max"


def _achievability(mdp: MDP, model: MDP, constraints: list[Constraint],
                   query: Multi) -> FilterOutcome:
    """Whether one strategy meets every bound, decided only outside the tolerance."""
    margin = multi_margin(model, constraints)
    if abs(margin.value) <= LP_TOLERANCE and not margin.witnessed:
        raise Undecided(
            f"multi(...) cannot be decided: the best strategy meets its bounds with a margin "
            f"of {margin.value:.1e}, within the linear programme's tolerance {LP_TOLERANCE:g}, "
            "and no exact witness was found", query.span)
    holds = margin.value > 0 or margin.witnessed
    values = np.zeros(mdp.num_states, dtype=bool)
    values[mdp.initial] = holds
    return FilterOutcome(holds, values, certified=margin.witnessed)


def _at_initial(mdp: MDP, value: float, error: float) -> Bounds:
    """Per state: the answer at the initial state, NaN (not computed) elsewhere."""
    point = np.full(mdp.num_states, np.nan)
    point[mdp.initial] = value
    return Bounds(point, point - error, point + error)
