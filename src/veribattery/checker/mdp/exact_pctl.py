"""PRISM properties on an MDP in exact rational arithmetic (``--exact``).

The recursion of :mod:`~veribattery.checker.mdp.formula` over an MDP whose
probabilities and rewards are rationals (:class:`~veribattery.explore.exact.mdp.ExactMdp`):
``Pmin``/``Pmax`` of ``F``/``U`` (and ``G``/``W``/``R`` by complement) and
``Rmin``/``Rmax`` of ``F``/``C`` by policy iteration in rationals with the final
strategy's optimality verified exactly (:mod:`~veribattery.checker.mdp.exact`);
``X``, ``U<=k``, ``U>=k``, ``U[a,b]``, ``C<=k`` and ``I=k`` by *k* exact Bellman
rounds (:mod:`~veribattery.checker.mdp.exact_steps`). ``P~p``/``R~r`` compare the
exact values with the exact bound; ``+ - * /`` and comparisons over queries, and
top-level filters, are computed exactly too.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import partial

import numpy as np
from gmpy2 import mpq

from veribattery._types import BoolArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.exact import ExactValues
from veribattery.checker.exact.expression import ExactStates, exact_state_values
from veribattery.checker.exact.filtered import (
    ExactCheckResult,
    ExactModelView,
    as_fraction,
    filtered,
)
from veribattery.checker.exact.numeric import exact_literal
from veribattery.checker.formula.leaves import (
    CONNECTIVES,
    as_mask,
    exact_step_bound,
    has_operator,
    integer_limit,
)
from veribattery.checker.mdp.exact import (
    exact_reach_reward,
    exact_total_reward,
    exact_until_reward,
)
from veribattery.checker.mdp.exact_reward_bounded import exact_reward_bounded
from veribattery.checker.mdp.exact_steps import exact_next, exact_rounds, exact_until
from veribattery.checker.mdp.formula import mdp_values, quantified_states
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.operators import (
    CONDITIONAL_ON_MDP,
    operator_objective,
    reward_structure,
)
from veribattery.checker.mdp.rational import ObjectArray
from veribattery.checker.mdp.system import Objective
from veribattery.checker.result import CheckResult
from veribattery.errors import CheckError
from veribattery.explore.exact.mdp import ExactMdp, ExactMdpRewards
from veribattery.explore.exact.program import needs_exact
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    BOUND_RELATIONS,
    Binary,
    Conditional,
    CosafeReach,
    Cumulative,
    Eventually,
    Expr,
    Filter,
    Globally,
    Instantaneous,
    Ite,
    LtlPath,
    Multi,
    Next,
    PathFormula,
    ProbOp,
    Property,
    Quantified,
    Reach,
    ReachUntil,
    Release,
    RewardBounded,
    RewardOp,
    TimeBound,
    TimeInterval,
    Total,
    Unary,
    Until,
    WeakUntil,
)
from veribattery.lang.property_rules import STEPS_REWARD

__all__ = ["ExactMdpModel", "check_mdp_exact", "require_exact_kernel"]

#: Why a multi(...) query is refused with --exact.
_NO_EXACT_MULTI = ("multi(...) has no exact MDP kernel: check it without --exact (its answer "
                   "is certified; an achievability on its boundary is decided in rationals)")

_ZERO = mpq(0)
_ONE = mpq(1)


@dataclass(frozen=True, slots=True)
class ExactMdpModel:
    """The checker's MDP with its exact numbers.

    :param mdp: the MDP (structure, labels, states) as the float engine reads it.
    :param exact: its probabilities and rewards as rationals (same entry order).
    """

    mdp: MDP
    exact: ExactMdp


def require_exact_kernel(formula: Expr) -> None:
    """Refuse, before any state is built, a ``multi(...)`` query, which has no exact
    kernel (the check would refuse it only after the build).

    :raises CheckError: at the first one.
    """
    for node in walk(formula):
        if type(node) is Multi:
            raise CheckError(_NO_EXACT_MULTI, node.span)


def check_mdp_exact(model: ExactMdpModel, prop: Property) -> ExactCheckResult:
    """Check *prop* on *model* in exact arithmetic; the answer at the initial states
    (the lowest, with the range over them, when several differ).

    :raises CheckError: for an operator without an exact MDP kernel (multi-objective
        queries, a filter inside an expression, arithmetic on an infinite reward) or
        ``P=?``/``R=?``.
    """
    if isinstance(prop.formula, Filter):
        return filtered(_view(model), prop, prop.formula)
    start = time.perf_counter()
    result = exact_values(model, prop.formula)
    initial = model.mdp.initial
    if initial.size == 0:
        raise CheckError("the model has no initial state", prop.span)
    if not isinstance(result, ExactValues):
        plain = CheckResult.at_initial(prop, result, initial, 0.0)
        return ExactCheckResult(prop, plain.values, plain.value, time.perf_counter() - start)
    enclosure = result.enclosure()
    lowest = min(initial, key=lambda s: (bool(result.infinite[s]), result.values[s]))
    highest = max(initial, key=lambda s: (bool(result.infinite[s]), result.values[s]))
    plain = CheckResult.at_initial(prop, enclosure, np.array([lowest]), 0.0)
    same = (result.infinite[lowest] == result.infinite[highest]
            and result.values[lowest] == result.values[highest])
    spread = None if same else (float(enclosure.value[lowest]), float(enclosure.value[highest]))
    exact = None if result.infinite[lowest] else as_fraction(result.values[lowest])
    upper = plain.upper if spread is None else float(enclosure.upper[highest])
    return ExactCheckResult(
        prop, plain.values, plain.value, time.perf_counter() - start, plain.lower, upper,
        plain.precise, plain.bounds, spread, exact=exact, exact_values=result)


def _view(model: ExactMdpModel) -> ExactModelView:
    """What a top-level filter reads of *model* (:func:`filtered`)."""
    mdp = model.mdp
    return ExactModelView(partial(exact_values, model), partial(state_set, model),
                          partial(check_mdp_exact, model), _states(mdp), mdp.variable_names,
                          mdp.initial)


def _states(mdp: MDP) -> np.ndarray:
    return np.zeros((mdp.num_states, 0), dtype=np.int64) if mdp.states is None else mdp.states


def exact_values(model: ExactMdpModel, formula: Expr) -> ExactValues | BoolArray:
    """Per-state value of *formula*: rationals for ``Pmin``/``Pmax``/``Rmin``/``Rmax=?``
    and expressions over them, booleans for state formulas."""
    match formula:
        case ProbOp(op="=?"):
            objective = operator_objective(formula)
            return ExactValues.finite(path_probs(model, formula.path, objective))
        case RewardOp(op="=?"):
            return path_rewards(model, formula, operator_objective(formula))
        case ProbOp() | RewardOp() | Quantified() | Unary(op="!"):
            return state_set(model, formula)
        case Binary(op=op) if op in CONNECTIVES:
            return state_set(model, formula)
        case Multi():
            raise CheckError(_NO_EXACT_MULTI, formula.span)
    return _expression(model, formula)


def _expression(model: ExactMdpModel, formula: Expr) -> ExactValues | BoolArray:
    """*formula* evaluated exactly in every state, its operators answered exactly
    (:func:`~veribattery.checker.exact.expression.exact_expression`)."""
    mdp = model.mdp
    at = ExactStates(_states(mdp), mdp.variable_names, mdp.labels)
    return exact_state_values(formula, at, partial(_operand, model), partial(_leaf, mdp))


def _leaf(mdp: MDP, expr: Expr) -> np.ndarray:
    """An operator-free expression's values in every state, in doubles."""
    found = mdp_values(mdp, expr)
    return found.value if isinstance(found, Bounds) else found


def _operand(model: ExactMdpModel, node: Expr) -> ExactValues | BoolArray:
    """An operator inside an expression, answered exactly."""
    if isinstance(node, Filter):
        raise CheckError("in exact arithmetic, filter(...) is answered at the top of a "
                         "property only", node.span)
    if isinstance(node, ProbOp | RewardOp) and node.op == "=?":
        return exact_values(model, node)
    return state_set(model, node)


def _opposite(objective: Objective) -> Objective:
    return "max" if objective == "min" else "min"


# ---------------------------------------------------------------------------
# State formulas
# ---------------------------------------------------------------------------


def state_set(model: ExactMdpModel, expr: Expr) -> BoolArray:
    """The states satisfying *expr*, bounded operators decided exactly."""
    if not has_operator(expr) and not needs_exact(expr):  # doubles decide it exactly
        leaf = mdp_values(model.mdp, expr)  # a bool variable's values come as 0/1 numbers
        return as_mask(leaf.value if isinstance(leaf, Bounds) else leaf, expr)
    match expr:
        case ProbOp() | RewardOp():
            return _bounded(model, expr)
        case Quantified(quantifier=quantifier, path=path):
            return quantified_states(model.mdp, quantifier, path, partial(state_set, model))
        case Unary(op="!", operand=operand):
            return ~state_set(model, operand)
        case Binary(op=op, left=left, right=right) if op in CONNECTIVES:
            return CONNECTIVES[op](state_set(model, left), state_set(model, right))
        case Ite(cond=cond, then=then, otherwise=otherwise):
            return np.where(state_set(model, cond), state_set(model, then),
                            state_set(model, otherwise))
        case Filter():
            raise CheckError("in exact arithmetic on an MDP, filter(...) is answered at the "
                             "top of a property only", expr.span)
    found = _expression(model, expr)  # a comparison of numbers, exactly
    if isinstance(found, ExactValues):
        raise CheckError("expected a boolean state formula", expr.span)
    return found


def _bounded(model: ExactMdpModel, op: ProbOp | RewardOp) -> BoolArray:
    """``P~p``/``R~r``: the exact optimum against the exact bound."""
    if op.op == "=?" or op.bound is None:
        raise CheckError("a query (=?) cannot be used as a state formula", op.span)
    objective = operator_objective(op)
    if isinstance(op, ProbOp):
        numbers = ExactValues.finite(path_probs(model, op.path, objective))
    else:
        numbers = path_rewards(model, op, objective)
    holds = np.asarray(BOUND_RELATIONS[op.op](numbers.values, exact_literal(op.bound)),
                       dtype=bool)
    return np.where(numbers.infinite, op.op in (">", ">="), holds)


# ---------------------------------------------------------------------------
# Arithmetic over operators
# ---------------------------------------------------------------------------

# ---------------------------------------------------------------------------
# Path formulas
# ---------------------------------------------------------------------------


def path_probs(model: ExactMdpModel, path: PathFormula, objective: Objective) -> ObjectArray:
    """Per-state exact ``Pmin``/``Pmax`` of *path*."""
    match path:
        case Next(operand=operand):
            return exact_next(model.mdp, model.exact.probabilities,
                              state_set(model, operand), objective)
        case Eventually(operand=operand, bound=bound):
            return _until(model, None, state_set(model, operand), bound, objective)
        case Until(left=left, right=right, bound=bound):
            return _until(model, state_set(model, left), state_set(model, right), bound,
                          objective)
        case Globally(operand=operand, bound=bound):  # G a = !(F !a)
            avoid = ~state_set(model, operand)
            return _complement(_until(model, None, avoid, bound, _opposite(objective)))
        case WeakUntil(left=left, right=right, bound=bound):  # a W b = !((a & !b) U (!a & !b))
            a, b = state_set(model, left), state_set(model, right)
            return _complement(_until(model, a & ~b, ~a & ~b, bound, _opposite(objective)))
        case Release(left=left, right=right, bound=bound):  # a R b = !(!a U !b)
            a, b = state_set(model, left), state_set(model, right)
            return _complement(_until(model, ~a, ~b, bound, _opposite(objective)))
        case RewardBounded(left=left, right=right, bound=bound):
            limit = integer_limit(bound.op, exact_literal(bound.value))
            return exact_reward_bounded(model.mdp, model.exact.probabilities,
                                        _structure(model, path), limit, state_set(model, left),
                                        state_set(model, right), objective=objective,
                                        span=path.span)
        case Conditional():
            raise CheckError(CONDITIONAL_ON_MDP, path.span)
        case LtlPath():
            from veribattery.checker.mdp.exact_ltl import exact_accepted_probability

            found = exact_accepted_probability(
                model.mdp, model.exact.probabilities, path, partial(state_set, model),
                negated=objective == "min")
            return _complement(found) if objective == "min" else found
    raise CheckError("this path formula has no exact MDP kernel (X, U, F, G, W, R and "
                     "reward-bounded F, U have)", path.span)


def _until(model: ExactMdpModel, remain: BoolArray | None, target: BoolArray,
           bound: TimeBound | TimeInterval | None, objective: Objective) -> ObjectArray:
    return exact_until(model.mdp, model.exact.probabilities, remain, target, bound, objective)


def _complement(values: ObjectArray) -> ObjectArray:
    return np.asarray(_ONE - values, dtype=object)


# ---------------------------------------------------------------------------
# Rewards
# ---------------------------------------------------------------------------


def path_rewards(model: ExactMdpModel, op: RewardOp, objective: Objective) -> ExactValues:
    """Per-state exact ``Rmin``/``Rmax`` over ``F``, ``a U b``, ``C``, ``C<=k`` or ``I=k``."""
    structure = _structure(model, op)
    mdp = model.mdp
    per_choice = structure.per_choice(mdp.choice_owner)
    everywhere = np.ones(mdp.num_states, dtype=bool)
    probabilities = model.exact.probabilities
    match op.path:
        case Reach(target=target):
            found = exact_reach_reward(mdp, per_choice, state_set(model, target),
                                       objective=objective, probabilities=probabilities)
            return ExactValues(found.values, found.infinite)
        case Total():
            found = exact_total_reward(mdp, per_choice, objective=objective,
                                       probabilities=probabilities)
            return ExactValues(found.values, found.infinite)
        case ReachUntil(left=left, right=right):  # co-safe: infinite once neither holds
            found = exact_until_reward(mdp, per_choice, state_set(model, left),
                                       state_set(model, right), objective=objective,
                                       probabilities=probabilities)
            return ExactValues(found.values, found.infinite)
        case CosafeReach():
            from veribattery.checker.mdp.exact_ltl import exact_cosafe_reward

            return ExactValues(*exact_cosafe_reward(
                mdp, probabilities, per_choice, op.path, partial(state_set, model),
                objective=objective))
        case Cumulative(bound=bound):
            zeros = np.full(mdp.num_states, _ZERO, dtype=object)
            return ExactValues.finite(exact_rounds(mdp, probabilities, zeros, everywhere, zeros,
                                                   objective, exact_step_bound(bound), per_choice))
        case Instantaneous(time=time_):
            state = np.asarray(structure.state, dtype=object)
            return ExactValues.finite(exact_rounds(mdp, probabilities, state, everywhere,
                                                   state, objective, exact_step_bound(time_)))
    raise CheckError("this reward formula has no exact MDP kernel (F, a U b, C, C<=k, I=k "
                     "have)",
                     op.path.span)


def _structure(model: ExactMdpModel, op: RewardOp | RewardBounded) -> ExactMdpRewards:
    """As :func:`~veribattery.checker.mdp.operators.reward_structure`, in rationals."""
    if op.reward == STEPS_REWARD:
        states, choices = model.mdp.num_states, model.mdp.num_choices
        return ExactMdpRewards(None, np.full(states, _ONE, dtype=object),
                               np.full(choices, _ZERO, dtype=object))
    reward_structure(model.mdp, op)  # (its checks: the floats are the rationals' shadows)
    return model.exact.reward(op.reward)


# ---------------------------------------------------------------------------
# Results
# ---------------------------------------------------------------------------


_TO_MPQ = np.frompyfunc(mpq, 1, 1)


