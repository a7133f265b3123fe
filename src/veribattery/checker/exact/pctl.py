"""PCTL model checking in exact rational arithmetic (``--exact``).

The same recursion as :mod:`~veribattery.checker.formula.pctl` over an
:class:`~veribattery.explore.exact.dtmc.ExactDTMC`: state formulas are masks, ``P``
and ``R`` operators are per-state rationals (:class:`ExactValues`), and
``P~p``/``R~r`` compare them with the bound exactly. The qualitative pre-pass
is the float checker's (prob0/prob1 are graph searches, identical on the exact
matrix, which has the same structure); the maybe states are then solved SCC by
SCC in rationals (:mod:`~veribattery.checker.exact.solve`), and step-bounded
operators iterate exact matrix-vector products. Infinite expected rewards are
kept in a separate mask.
"""

from __future__ import annotations

import functools
import time

import numpy as np

from veribattery._types import BoolArray
from veribattery.checker.exact import steady, storm
from veribattery.checker.exact.expression import ExactStates, exact_state_values
from veribattery.checker.exact.filtered import (
    ExactCheckResult,
    ExactModelView,
    as_fraction,
    filtered,
)
from veribattery.checker.exact.numeric import (
    _ONE,
    _ZERO,
    ExactValues,
    _next,
    _power,
    _until,
    exact_literal,
    indicator,
    reach_rewards,
    until_probs,
)
from veribattery.checker.formula import ctl
from veribattery.checker.formula.leaves import (
    CONNECTIVES,
    as_mask,
    exact_step_bound,
    has_operator,
    leaf_values,
    require_nonnegative_rewards,
)
from veribattery.checker.result import CheckResult
from veribattery.checker.workspace import Workspace
from veribattery.errors import CheckError, UndefinedResult
from veribattery.explore.exact.dtmc import ExactDTMC, ExactRewards
from veribattery.explore.exact.program import needs_exact
from veribattery.explore.exact.rational import ObjectArray
from veribattery.lang.expressions import operand_chain
from veribattery.lang.nodes import (
    BOUND_RELATIONS,
    Binary,
    Conditional,
    ConditionalReach,
    CosafeReach,
    Cumulative,
    Eventually,
    Expr,
    Filter,
    Globally,
    Instantaneous,
    Ite,
    LongRun,
    LtlPath,
    Next,
    PathFormula,
    ProbOp,
    Property,
    Quantified,
    Reach,
    ReachNext,
    ReachUntil,
    Release,
    RewardBounded,
    RewardOp,
    SteadyOp,
    Total,
    Unary,
    Until,
    WeakUntil,
)
from veribattery.lang.property_rules import STEPS_REWARD

__all__ = ["ExactCheckResult", "check_exact", "exact_values"]


def check_exact(
    model: ExactDTMC, prop: Property | Expr, *, workspace: Workspace | None = None,
) -> ExactCheckResult:
    """Check *prop* on *model* in exact arithmetic and report it at the initial states.

    A ``P~p``/``R~r`` bound is read from its literal's digits (or the exact fraction a
    decided property writes there: :mod:`~veribattery.explore.exact.decided`).

    :param workspace: the caches to use and fill (graph searches, prepared systems),
        shared with the other checks given it; None: a new one for this check alone.
    :raises CheckError: when the property cannot be checked on this model.
    """
    prop = prop if isinstance(prop, Property) else Property(prop)
    workspace = Workspace() if workspace is None else workspace
    if isinstance(prop.formula, Filter):
        return filtered(_view(model, workspace), prop, prop.formula)
    start = time.perf_counter()
    result = exact_values(model, prop.formula, workspace=workspace)
    initial = model.dtmc.initial
    if isinstance(result, ExactValues):
        plain = CheckResult.at_initial(prop, result.enclosure(), initial, 0.0)
        first = int(initial[0])
        exact = None if result.infinite[first] else as_fraction(result.values[first])
        return ExactCheckResult(
            prop, plain.values, plain.value, time.perf_counter() - start, plain.lower,
            plain.upper, plain.precise, plain.bounds, exact=exact, exact_values=result)
    plain = CheckResult.at_initial(prop, result, initial, 0.0)
    return ExactCheckResult(prop, plain.values, plain.value, time.perf_counter() - start)


def _view(model: ExactDTMC, workspace: Workspace) -> ExactModelView:
    """What a top-level filter reads of *model* (:func:`filtered`)."""
    dtmc = model.dtmc

    def mask(expr: Expr) -> BoolArray:
        found = exact_values(model, expr, workspace=workspace)
        if isinstance(found, ExactValues):
            raise CheckError("expected a boolean state formula", expr.span)
        return found

    return ExactModelView(
        functools.partial(exact_values, model, workspace=workspace), mask,
        functools.partial(check_exact, model, workspace=workspace),
        dtmc.states, dtmc.variable_names, dtmc.initial)


def exact_values(
    model: ExactDTMC, formula: Expr, *, workspace: Workspace | None = None,
) -> ExactValues | BoolArray:
    """Per-state value of *formula*: rationals for ``P=?``/``R=?``, booleans otherwise.

    :param workspace: as for :func:`check_exact`.
    """
    workspace = Workspace() if workspace is None else workspace
    if isinstance(formula, ProbOp) and formula.op == "=?":
        return ExactValues.finite(path_probs(model, workspace, formula.path))
    if isinstance(formula, RewardOp | SteadyOp) and formula.op == "=?":
        return _query(model, workspace, formula)
    if _is_state_formula(formula):
        return state_set(model, workspace, formula)
    return _expression(model, workspace, formula)


def _is_state_formula(formula: Expr) -> bool:
    """Whether *formula* is a state formula the recursion of :func:`state_set` takes: a
    bounded operator, ``A``/``E``, a connective. (Plain expressions, numbers and
    comparisons over them are :func:`_expression`'s.)"""
    return isinstance(formula, ProbOp | RewardOp | SteadyOp | Quantified) or (
        isinstance(formula, Binary) and formula.op in CONNECTIVES) or (
        isinstance(formula, Unary) and formula.op == "!")


def _expression(model: ExactDTMC, workspace: Workspace, formula: Expr) -> ExactValues | BoolArray:
    """*formula* evaluated exactly in every state, its operators answered exactly
    (:func:`~veribattery.checker.exact.expression.exact_expression`)."""
    dtmc = model.dtmc
    at = ExactStates(dtmc.states, dtmc.variable_names, dtmc.labels)
    return exact_state_values(formula, at, functools.partial(_operand, model, workspace),
                              functools.partial(leaf_values, dtmc))


def _operand(model: ExactDTMC, workspace: Workspace, node: Expr) -> ExactValues | BoolArray:
    """An operator inside an expression, answered exactly."""
    if isinstance(node, Filter):
        raise CheckError("in exact arithmetic, filter(...) is answered at the top of a "
                         "property only", node.span)
    if isinstance(node, ProbOp) and node.op == "=?":
        return ExactValues.finite(path_probs(model, workspace, node.path))
    if isinstance(node, RewardOp | SteadyOp) and node.op == "=?":
        return _query(model, workspace, node)
    return state_set(model, workspace, node)


def _query(model: ExactDTMC, workspace: Workspace, op: RewardOp | SteadyOp) -> ExactValues:
    """The values of an ``R=?`` or ``S=?`` query."""
    if isinstance(op, RewardOp):
        return path_rewards(model, workspace, op)
    counted = indicator(state_set(model, workspace, op.operand))
    return ExactValues.finite(steady.long_run_values(model, workspace, counted))


# ---------------------------------------------------------------------------
# State formulas
# ---------------------------------------------------------------------------

def state_set(model: ExactDTMC, workspace: Workspace, expr: Expr) -> BoolArray:
    """The states satisfying *expr*, bounded operators decided exactly."""
    if not has_operator(expr) and not needs_exact(expr):  # doubles decide it exactly
        return as_mask(leaf_values(model.dtmc, expr), expr)
    match expr:
        case ProbOp() | RewardOp() | SteadyOp():
            return _bounded_operator(model, workspace, expr)
        case Quantified(quantifier=quantifier, path=LtlPath() as path):  # graph searches
            from veribattery.checker.formula.ltl import ltl_quantified

            return ltl_quantified(model.dtmc.transitions, quantifier, path,
                                  functools.partial(state_set, model, workspace))
        case Quantified(quantifier=quantifier, path=path):  # graph searches: exact already
            return ctl.quantified_path(model.dtmc.transitions, quantifier, path,
                                       functools.partial(state_set, model, workspace),
                                       workspace=workspace)
        case Unary(op="!", operand=operand):
            return ~state_set(model, workspace, operand)
        case Binary(op="&" | "|" as op):  # a chain of thousands: a loop, not a recursion
            masks = (state_set(model, workspace, operand) for operand in operand_chain(expr, op))
            return functools.reduce(CONNECTIVES[op], masks)
        case Binary(op=op, left=left, right=right) if op in CONNECTIVES:
            return CONNECTIVES[op](state_set(model, workspace, left),
                                    state_set(model, workspace, right))
        case Ite(cond=cond, then=then, otherwise=otherwise) if has_operator(expr):
            return np.where(state_set(model, workspace, cond), state_set(model, workspace, then),
                            state_set(model, workspace, otherwise))
    found = _expression(model, workspace, expr)  # a comparison of numbers, exactly
    if isinstance(found, ExactValues):
        raise CheckError("expected a boolean state formula", expr.span)
    return found


def _bounded_operator(model: ExactDTMC, workspace: Workspace,
                      op: ProbOp | RewardOp | SteadyOp) -> BoolArray:
    if op.op == "=?" or op.bound is None:
        raise CheckError("a query (=?) cannot be used as a state formula", op.span)
    if isinstance(op, ProbOp):
        numbers = ExactValues.finite(path_probs(model, workspace, op.path))
    else:
        numbers = _query(model, workspace, op)
    holds = np.asarray(BOUND_RELATIONS[op.op](numbers.values, exact_literal(op.bound)),
                       dtype=bool)
    return np.where(numbers.infinite, op.op in (">", ">="), holds)


# ---------------------------------------------------------------------------
# Path formulas
# ---------------------------------------------------------------------------


def path_probs(model: ExactDTMC, workspace: Workspace, path: PathFormula) -> ObjectArray:
    """Per-state exact probability of *path* (``X``, ``U``, ``F``, ``G``, step-bounded too)."""
    everywhere = np.ones(model.dtmc.num_states, dtype=bool)
    match path:
        case Next(operand=operand):
            return _next(model, state_set(model, workspace, operand))
        case Until(left=left, right=right, bound=bound):
            a, b = state_set(model, workspace, left), state_set(model, workspace, right)
            return _until(model, workspace, a, b, bound)
        case Eventually(operand=operand, bound=bound):
            target = state_set(model, workspace, operand)
            return _until(model, workspace, everywhere, target, bound)
        case Globally(operand=operand, bound=bound):
            avoid = ~state_set(model, workspace, operand)
            escape = _until(model, workspace, everywhere, avoid, bound)
            return np.asarray(_ONE - escape, dtype=object)
        case WeakUntil(left=left, right=right, bound=bound):  # !((a & !b) U (!a & !b))
            a, b = state_set(model, workspace, left), state_set(model, workspace, right)
            return np.asarray(_ONE - _until(model, workspace, a & ~b, ~a & ~b, bound),
                              dtype=object)
        case Release(left=left, right=right, bound=bound):  # a R b = !(!a U !b)
            a, b = state_set(model, workspace, left), state_set(model, workspace, right)
            return np.asarray(_ONE - _until(model, workspace, ~a, ~b, bound), dtype=object)
        case RewardBounded() | Conditional():
            return _storm_formula(model, workspace, path)
        case LtlPath():
            from veribattery.checker.exact.ltl import exact_ltl_probs  # when met

            return exact_ltl_probs(model, workspace, path,
                                   functools.partial(state_set, model, workspace))
    raise UndefinedResult(
        f"{type(path).__name__} formulas are not supported in exact arithmetic", path.span)


def _storm_formula(model: ExactDTMC, workspace: Workspace,
                   path: RewardBounded | Conditional) -> ObjectArray:
    """Storm's reward-bounded and conditional formulas (:mod:`~veribattery.checker.exact.storm`)."""
    if isinstance(path, RewardBounded):
        return storm.reward_bounded_probs(model, workspace, path, state_set=state_set)
    return storm.conditional_probs(model, workspace, path, state_set=state_set)


# ---------------------------------------------------------------------------
# Rewards
# ---------------------------------------------------------------------------


def path_rewards(model: ExactDTMC, workspace: Workspace, op: RewardOp) -> ExactValues:
    """Per-state exact expected reward of ``R{..}`` over ``F``, ``C<=k``, ``I=k``, ``C``,
    ``S`` or Storm's conditional ``F a || F b``."""
    structure = _reward_structure(model, op)
    zero = indicator(np.zeros(model.dtmc.num_states, dtype=bool))
    everywhere = np.ones(model.dtmc.num_states, dtype=bool)
    match op.path:
        case Reach(target=target):
            reached = state_set(model, workspace, target)
            return reach_rewards(model, workspace, structure.total, reached)
        case Cumulative(bound=bound):
            steps = exact_step_bound(bound)
            return ExactValues.finite(_power(model, everywhere, zero, structure.total, steps))
        case Instantaneous(time=time_):
            steps = exact_step_bound(time_)
            return ExactValues.finite(_power(model, everywhere, structure.state, zero, steps))
        case ConditionalReach():
            return storm.conditional_reach_rewards(model, workspace, structure, op.path,
                                                   state_set=state_set)
        case ReachUntil(left=left, right=right):  # the reward until b, where a U b is sure
            a, b = state_set(model, workspace, left), state_set(model, workspace, right)
            sure = np.asarray(until_probs(model, workspace, a, b) == _ONE, dtype=bool)
            found = reach_rewards(model, workspace, structure.total, b)
            return ExactValues(np.where(sure, found.values, _ZERO), found.infinite | ~sure)
        case LongRun():
            return ExactValues.finite(steady.long_run_values(model, workspace, structure.total))
        case Total():
            return steady.total_rewards(model, workspace, structure.total)
        case ReachNext(target=target):  # co-safe X phi: the first step's reward, if sure
            outside = ~state_set(model, workspace, target)
            sure = model.dtmc.transitions @ outside.astype(np.float64) == 0  # graph only
            return ExactValues(np.where(sure, structure.total, _ZERO), ~sure)
        case CosafeReach():
            from veribattery.checker.exact.ltl import exact_cosafe_rewards

            return exact_cosafe_rewards(model, workspace, structure.total, op.path,
                                        functools.partial(state_set, model, workspace))
    raise UndefinedResult(
        f"{type(op.path).__name__} reward paths are not supported in exact arithmetic",
        op.path.span)


def _reward_structure(model: ExactDTMC, op: RewardOp) -> ExactRewards:
    if op.reward == STEPS_REWARD:  # Storm's T=?: one per step
        states = model.dtmc.num_states
        return ExactRewards(None, indicator(np.ones(states, dtype=bool)),
                            indicator(np.zeros(states, dtype=bool)))
    try:
        structure = model.reward(op.reward)
    except (KeyError, IndexError):
        key = "" if op.reward is None else f" {op.reward!r}"
        raise CheckError(f"the model has no reward structure{key}", op.span) from None
    require_nonnegative_rewards(structure.name, (structure.state, structure.transition), op)
    return structure
