"""PRISM properties on an MDP in exact rational arithmetic (``--exact``).

The recursion of :mod:`~veribattery.checker.mdp.formula` over an MDP whose
probabilities and rewards are rationals (:class:`~veribattery.explore.exact.mdp.ExactMdp`):
``Pmin``/``Pmax`` of ``F``/``U`` (and ``G``/``W``/``R`` by complement) and
``Rmin``/``Rmax`` of ``F``/``C`` by policy iteration in rationals with the final
strategy's optimality verified exactly (:mod:`~veribattery.checker.mdp.exact`);
``X``, ``U<=k``, ``U>=k``, ``U[a,b]``, ``C<=k`` and ``I=k`` by *k* exact Bellman
rounds. ``P~p``/``R~r`` compare the exact values with the exact bound.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from fractions import Fraction

import numpy as np
from gmpy2 import mpq

from veribattery._types import BoolArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.exact import ExactCheckResult, ExactValues
from veribattery.checker.exact.numeric import exact_literal
from veribattery.checker.formula import filters
from veribattery.checker.formula.leaves import CONNECTIVES, as_mask, has_operator, step_bound
from veribattery.checker.mdp.exact import (
    exact_reach_probability,
    exact_reach_reward,
    exact_total_reward,
)
from veribattery.checker.mdp.formula import mdp_values
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.rational import ObjectArray
from veribattery.checker.mdp.system import Objective
from veribattery.checker.result import CheckResult
from veribattery.errors import CheckError, Span
from veribattery.explore.exact.mdp import ExactMdp, ExactMdpRewards
from veribattery.lang.nodes import (
    BOUND_RELATIONS,
    Binary,
    Cumulative,
    Eventually,
    Expr,
    Filter,
    Globally,
    Instantaneous,
    Ite,
    Next,
    PathFormula,
    ProbOp,
    Property,
    Reach,
    Release,
    RewardOp,
    TimeBound,
    TimeInterval,
    Total,
    Unary,
    Until,
    WeakUntil,
)

__all__ = ["ExactMdpModel", "check_mdp_exact"]

_ZERO = mpq(0)
_ONE = mpq(1)


@dataclass(frozen=True, slots=True)
class ExactMdpModel:
    """The checker's MDP with its exact numbers and the property's exact bounds.

    :param mdp: the MDP (structure, labels, states) as the float engine reads it.
    :param exact: its probabilities and rewards as rationals (same entry order).
    :param bounds: the exact value of each ``P~p``/``R~r`` bound, by its span.
    """

    mdp: MDP
    exact: ExactMdp
    bounds: Mapping[Span, mpq]


def check_mdp_exact(model: ExactMdpModel, prop: Property) -> ExactCheckResult:
    """Check *prop* on *model* in exact arithmetic; the answer at the initial states
    (the lowest, with the range over them, when several differ).

    :raises CheckError: for an operator without an exact MDP kernel (filters,
        multi-objective queries, numeric expressions over operators) or ``P=?``/``R=?``.
    """
    start = time.perf_counter()
    if isinstance(prop.formula, Filter):
        return _filtered(model, prop, prop.formula, start)
    result = exact_values(model, prop.formula)
    initial = model.mdp.initial
    if initial.size == 0:
        raise CheckError("the model has no initial state", prop.span)
    if not isinstance(result, ExactValues):
        plain = CheckResult.at_initial(prop, result, initial, 0.0)
        return ExactCheckResult(prop, plain.values, plain.value, time.perf_counter() - start)
    enclosure = _enclosure(result)
    lowest = min(initial, key=lambda s: (not result.infinite[s], result.values[s]))
    highest = max(initial, key=lambda s: (bool(result.infinite[s]), result.values[s]))
    plain = CheckResult.at_initial(prop, enclosure, np.array([lowest]), 0.0)
    same = (result.infinite[lowest] == result.infinite[highest]
            and result.values[lowest] == result.values[highest])
    spread = None if same else (float(enclosure.value[lowest]), float(enclosure.value[highest]))
    exact = None if result.infinite[lowest] else _fraction(result.values[lowest])
    upper = plain.upper if spread is None else float(enclosure.upper[highest])
    return ExactCheckResult(
        prop, plain.values, plain.value, time.perf_counter() - start, plain.lower, upper,
        plain.precise, plain.bounds, spread, exact=exact, exact_values=result)


def _filtered(model: ExactMdpModel, prop: Property, node: Filter,
              start: float) -> ExactCheckResult:
    """A top-level ``filter(op, operand, states)``: the float outcome of its enclosure
    (:func:`~veribattery.checker.formula.filters.apply_filter`: listings, counts, booleans,
    which are exact), and for a number the exact value it picks or sums."""
    mdp = model.mdp
    where = (np.ones(mdp.num_states, dtype=bool) if node.states is None
             else state_set(model, node.states))
    inner = exact_values(model, node.operand)
    per_state = _enclosure(inner) if isinstance(inner, ExactValues) else inner
    states = _states(mdp)
    outcome = filters.apply_filter(node.op, per_state, where, states, mdp.variable_names,
                                   node.span)
    if outcome.value is None and node.op.startswith("arg"):  # the listed states, as a set
        mask = np.asarray(outcome.values, dtype=bool)
        plain = CheckResult.at_initial(prop, mask, mdp.initial, time.perf_counter() - start)
        return ExactCheckResult(prop, plain.values, plain.value, plain.time_s,
                                printed=outcome.printed)
    if outcome.value is None:  # print, printall: the listing, and the operand's answer
        answer = check_mdp_exact(model, replace(prop, formula=node.operand))
        return replace(answer, property=prop, printed=outcome.printed)
    plain = CheckResult.of_answer(prop, outcome, time.perf_counter() - start)
    if not isinstance(inner, ExactValues) or node.op not in _EXACT_FILTERS:
        return ExactCheckResult(prop, plain.values, plain.value, plain.time_s, plain.lower,
                                plain.upper, plain.precise, plain.bounds, plain.value_range,
                                plain.printed)
    value, infinite = _filter_exact(node.op, inner, where, states)
    return ExactCheckResult(
        prop, plain.values, plain.value, plain.time_s, plain.lower, plain.upper,
        plain.precise, plain.bounds, plain.value_range, plain.printed,
        exact=None if infinite else _fraction(value), exact_values=inner)


#: The filters whose number is picked or summed exactly (``range``: its lowest value).
_EXACT_FILTERS = frozenset({"state", "first", "min", "max", "range", "sum", "avg"})


def _filter_exact(op: str, inner: ExactValues, where: BoolArray,
                  states: np.ndarray) -> tuple[mpq, bool]:
    """The exact number of a numeric filter over *where*, and whether it is infinite."""
    picked = np.flatnonzero(where)
    if op in ("sum", "avg"):
        if inner.infinite[picked].any():
            return _ZERO, True
        total = sum(inner.values[picked], _ZERO)
        return (total if op == "sum" else total / picked.size), False
    if op == "first":
        order = filters.state_order(states)
        picked = order[where[order]][:1]
    ranked = sorted(picked, key=lambda s: (bool(inner.infinite[s]), inner.values[s]))
    state = ranked[-1] if op == "max" else ranked[0]
    return inner.values[state], bool(inner.infinite[state])


def _states(mdp: MDP) -> np.ndarray:
    return np.zeros((mdp.num_states, 0), dtype=np.int64) if mdp.states is None else mdp.states


def exact_values(model: ExactMdpModel, formula: Expr) -> ExactValues | BoolArray:
    """Per-state value of *formula*: rationals for ``Pmin``/``Pmax``/``Rmin``/``Rmax=?``,
    booleans for state formulas."""
    match formula:
        case ProbOp(op="=?"):
            return ExactValues.finite(path_probs(model, formula.path, _direction(formula)))
        case RewardOp(op="=?"):
            return path_rewards(model, formula, _direction(formula))
    if has_operator(formula):
        return state_set(model, formula)
    leaf = mdp_values(model.mdp, formula)
    if isinstance(leaf, Bounds):
        raise CheckError("--exact checks P and R operators and boolean formulas; "
                         "this is a numeric state expression", formula.span)
    return leaf


def _direction(op: ProbOp | RewardOp) -> Objective:
    """As on the float engine: the operator's own ``min``/``max``, else the one that
    quantifies over every strategy (``P>=p`` reads the minimum)."""
    if op.direction is not None:
        return op.direction
    if op.op == "=?":
        name = "P" if isinstance(op, ProbOp) else "R"
        raise CheckError(f"{name}=? on an MDP has no single value: use {name}min=? or "
                         f"{name}max=?", op.span)
    return "max" if op.op in ("<", "<=") else "min"


def _opposite(objective: Objective) -> Objective:
    return "max" if objective == "min" else "min"


# ---------------------------------------------------------------------------
# State formulas
# ---------------------------------------------------------------------------


def state_set(model: ExactMdpModel, expr: Expr) -> BoolArray:
    """The states satisfying *expr*, bounded operators decided exactly."""
    if not has_operator(expr):
        leaf = mdp_values(model.mdp, expr)  # a bool variable's values come as 0/1 numbers
        return as_mask(leaf.value if isinstance(leaf, Bounds) else leaf, expr)
    match expr:
        case ProbOp() | RewardOp():
            return _bounded(model, expr)
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
    raise CheckError("in exact arithmetic on an MDP, P and R operators are queried "
                     "(Pmax=? ...) or bounded and combined with ! & | => <=> ?: only",
                     expr.span)


def _bounded(model: ExactMdpModel, op: ProbOp | RewardOp) -> BoolArray:
    """``P~p``/``R~r``: the exact optimum against the exact bound."""
    if op.op == "=?" or op.bound is None:
        raise CheckError("a query (=?) cannot be used as a state formula", op.span)
    objective = _direction(op)
    if isinstance(op, ProbOp):
        numbers = ExactValues.finite(path_probs(model, op.path, objective))
    else:
        numbers = path_rewards(model, op, objective)
    bound = model.bounds.get(op.bound.span)
    bound = exact_literal(op.bound) if bound is None else bound
    holds = np.asarray(BOUND_RELATIONS[op.op](numbers.values, bound), dtype=bool)
    return np.where(numbers.infinite, op.op in (">", ">="), holds)


# ---------------------------------------------------------------------------
# Path formulas
# ---------------------------------------------------------------------------


def path_probs(model: ExactMdpModel, path: PathFormula, objective: Objective) -> ObjectArray:
    """Per-state exact ``Pmin``/``Pmax`` of *path*."""
    match path:
        case Next(operand=operand):
            target = _indicator(state_set(model, operand))
            return _bellman(model, target, objective)
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
    raise CheckError("this path formula has no exact MDP kernel (X, U, F, G, W, R have)",
                     path.span)


def _until(model: ExactMdpModel, remain: BoolArray | None, target: BoolArray,
           bound: TimeBound | TimeInterval | None, objective: Objective) -> ObjectArray:
    """``remain U target`` within its step interval."""
    n = model.mdp.num_states
    remain = np.ones(n, dtype=bool) if remain is None else remain
    if bound is None:
        return _reach(model, remain, target, objective)
    if isinstance(bound, TimeInterval):
        low, high = step_bound(bound.low), step_bound(bound.high)
    elif bound.op in ("<=", "<"):
        low, high = 0, step_bound(bound.value) - (bound.op == "<")
    elif bound.op == "=":
        low = high = step_bound(bound.value)
    else:  # >= k, > k: remain for k steps, then remain U target
        steps = step_bound(bound.value) + (bound.op == ">")
        later = _reach(model, remain, target, objective)
        return _rounds(model, later, remain, _zeros(n), objective, steps)
    if high < low:
        return _zeros(n)
    start = _indicator(target)
    window = _rounds(model, start, remain & ~target, start, objective, high - low)
    return _rounds(model, window, remain, _zeros(n), objective, low)


def _reach(model: ExactMdpModel, remain: BoolArray, target: BoolArray,
           objective: Objective) -> ObjectArray:
    """Unbounded ``remain U target`` by exact policy iteration."""
    found = exact_reach_probability(model.mdp, target, objective=objective, remain=remain,
                                    probabilities=model.exact.probabilities)
    return found.values


def _complement(values: ObjectArray) -> ObjectArray:
    return np.asarray(_ONE - values, dtype=object)


# ---------------------------------------------------------------------------
# Rewards
# ---------------------------------------------------------------------------


def path_rewards(model: ExactMdpModel, op: RewardOp, objective: Objective) -> ExactValues:
    """Per-state exact ``Rmin``/``Rmax`` over ``F``, ``C``, ``C<=k`` or ``I=k``."""
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
        case Cumulative(bound=bound):
            zeros = _zeros(mdp.num_states)
            return ExactValues.finite(_rounds(model, zeros, everywhere, zeros, objective,
                                              step_bound(bound), per_choice))
        case Instantaneous(time=time_):
            state = np.asarray(structure.state, dtype=object)
            return ExactValues.finite(_rounds(model, state, everywhere, state, objective,
                                              step_bound(time_)))
    raise CheckError("this reward formula has no exact MDP kernel (F, C, C<=k, I=k have)",
                     op.path.span)


def _structure(model: ExactMdpModel, op: RewardOp) -> ExactMdpRewards:
    try:
        return model.exact.reward(op.reward)
    except (KeyError, IndexError):
        raise CheckError(f"unknown reward structure {op.reward!r}", op.span) from None


# ---------------------------------------------------------------------------
# Exact Bellman rounds
# ---------------------------------------------------------------------------


def _rounds(model: ExactMdpModel, start: ObjectArray, moving: BoolArray, fixed: ObjectArray,
            objective: Objective, steps: int, offset: ObjectArray | None = None
            ) -> ObjectArray:
    """*steps* rounds of ``x(s) = opt_a (o_a + P_a x)`` on the *moving* states, the
    others held at *fixed*."""
    x = start
    for _ in range(steps):
        x = np.where(moving, _bellman(model, x, objective, offset), fixed)
    return np.asarray(x, dtype=object)


def _bellman(model: ExactMdpModel, x: ObjectArray, objective: Objective,
             offset: ObjectArray | None = None) -> ObjectArray:
    """One exact Bellman image: per state, the best choice's ``o_a + P_a x``."""
    P = model.mdp.transitions
    products = model.exact.probabilities * x[P.indices]
    rows = np.add.reduceat(products, P.indptr[:-1])  # every choice has an entry
    if offset is not None:
        rows = rows + offset
    reduce = np.maximum if objective == "max" else np.minimum
    return np.asarray(reduce.reduceat(rows, model.mdp.row_groups[:-1]), dtype=object)


def _indicator(mask: BoolArray) -> ObjectArray:
    return np.asarray(np.where(mask, _ONE, _ZERO), dtype=object)


def _zeros(n: int) -> ObjectArray:
    return np.full(n, _ZERO, dtype=object)


# ---------------------------------------------------------------------------
# Results
# ---------------------------------------------------------------------------


_TO_MPQ = np.frompyfunc(mpq, 1, 1)


def _enclosure(values: ExactValues) -> Bounds:
    """Certified float bounds of exact values: the nearest double, widened by one unit
    in the last place unless it is the value itself (infinities stand for themselves)."""
    floats = values.floats()
    represented = values.infinite.copy()
    finite = np.flatnonzero(~values.infinite)
    if finite.size:
        represented[finite] = np.asarray(_TO_MPQ(floats[finite]) == values.values[finite],
                                         dtype=bool)
    lower = np.where(represented, floats, np.nextafter(floats, -np.inf))
    upper = np.where(represented, floats, np.nextafter(floats, np.inf))
    return Bounds(floats, lower, upper)


def _fraction(value: mpq) -> Fraction:
    return Fraction(int(value.numerator), int(value.denominator))
