"""PRISM properties on an MDP: ``Pmin``/``Pmax`` and ``Rmin``/``Rmax`` with certified
bounds, and the state formulas, expressions and filters around them.

PRISM's rules for MDPs: ``P=?`` and ``R=?`` are errors (the value depends on the
strategy: say ``Pmin``/``Pmax``); ``P~p`` quantifies over every strategy, so
``P>=p`` reads the minimum and ``P<=p`` the maximum (an explicit ``Pmin``/``Pmax``
is kept). A bound is decided from the certified interval; a state whose interval
straddles it raises :class:`~veribattery.checker.formula.intervals.Undecided`, never a
guess (the pipeline settles it in exact arithmetic where the model allows).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import cast

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.formula import filters, intervals
from veribattery.checker.formula.intervals import Result
from veribattery.checker.formula.leaves import (
    as_mask,
    has_operator,
    literal_number,
    reward_limit,
    step_bound,
)
from veribattery.checker.mdp import cosafe, stepped
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.operators import (
    CONDITIONAL_ON_MDP,
    operator_objective,
    reward_structure,
)
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.reward_bounded import reward_bounded_reach
from veribattery.checker.mdp.rewards import reach_reward, total_reward
from veribattery.checker.mdp.system import Objective
from veribattery.errors import CheckError
from veribattery.explore.compile.expr import compile_expr
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    Conditional,
    CosafeReach,
    Cumulative,
    Eventually,
    Expr,
    Filter,
    Globally,
    Ident,
    Instantaneous,
    Ite,
    LabelRef,
    LtlPath,
    Multi,
    Next,
    PathFormula,
    ProbOp,
    Quantified,
    Reach,
    ReachNext,
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

__all__ = ["mdp_answer", "mdp_values", "quantified_states"]



def _opposite(objective: Objective) -> Objective:
    """The objective whose complement a dual formula (``G``, ``W``, ``R``) reads."""
    return "max" if objective == "min" else "min"


def mdp_answer(mdp: MDP, formula: Expr,
               progress: Progress | None = None) -> filters.FilterOutcome:
    """The answer PRISM reports: a top-level filter's value, else the value at the
    single initial state, the range over several, or ``forall`` for a boolean.

    :param progress: told how far each long solve is (:func:`mdp_values`).
    """
    printed: tuple[str, ...] = ()
    if isinstance(formula, Multi):
        # Imported here: the LP (scipy.optimize) is not needed for any other formula.
        from veribattery.checker.mdp.multi_formula import multi_answer

        return multi_answer(mdp, formula, partial(_mask, mdp, progress))
    if isinstance(formula, Filter):
        outcome = _filter(mdp, progress, formula)
        if outcome.value is not None:
            return outcome
        per_state, printed = _as_result(outcome.values), outcome.printed
    else:
        per_state = _values(mdp, progress, formula)
    if mdp.initial.size == 0:
        raise CheckError("the model has no initial state", formula.span)
    default = "forall" if not isinstance(per_state, Bounds) else (
        "state" if mdp.initial.size == 1 else "range")
    answer = filters.apply_filter(default, per_state, mdp.initial_mask, _states(mdp),
                                  mdp.variable_names, formula.span)
    return replace(answer, printed=printed)


def mdp_values(mdp: MDP, formula: Expr, progress: Progress | None = None) -> Result:
    """Per-state value of *formula*: certified numbers or a boolean mask.

    :param progress: told how far each long solve is (``(done, total, unit)``).
    """
    return _values(mdp, progress, formula)


def _values(mdp: MDP, progress: Progress | None, formula: Expr) -> Result:
    match formula:
        case ProbOp(op="=?"):
            return _path(mdp, progress, formula.path, operator_objective(formula))
        case RewardOp(op="=?"):
            return _reward(mdp, progress, formula, operator_objective(formula))
        case ProbOp() | RewardOp():
            return _bounded(mdp, progress, formula)
        case Filter():
            return _filter_everywhere(mdp, progress, formula)
        case Quantified(quantifier=quantifier, path=path):
            return _ctl(mdp, progress, quantifier, path)
    if not has_operator(formula):
        return _leaf(mdp, formula)
    return _compound(mdp, progress, formula)


def _bounded(mdp: MDP, progress: Progress | None, op: ProbOp | RewardOp) -> BoolArray:
    """``P~p``/``R~r`` as a mask, decided from the certified interval."""
    assert op.bound is not None
    threshold = literal_number(op.bound)
    query = replace(op, op="=?", bound=None, direction=operator_objective(op))
    numbers = _values(mdp, progress, query)
    assert isinstance(numbers, Bounds)
    holds, undecided = numbers.compare(op.op, threshold)
    if undecided.any():
        raise intervals.Undecided.straddled(op.op, threshold, numbers, undecided, op.span)
    return np.asarray(holds, dtype=bool)


def _mask(mdp: MDP, progress: Progress | None, expr: Expr) -> BoolArray:
    result = _values(mdp, progress, expr)
    if isinstance(result, Bounds):
        return as_mask(result.value, expr)
    return as_mask(result, expr)


def _path(mdp: MDP, progress: Progress | None, path: PathFormula,
          objective: Objective) -> Bounds:
    """``Pmin``/``Pmax`` of a path formula in every state."""
    match path:
        case Next(operand=operand):
            return stepped.next_probability(mdp, _mask(mdp, progress, operand),
                                            objective=objective).bounds
        case Eventually(operand=operand, bound=bound):
            return _until(mdp, progress, None, _mask(mdp, progress, operand), bound, objective)
        case Until(left=left, right=right, bound=bound):
            return _until(mdp, progress, _mask(mdp, progress, left),
                          _mask(mdp, progress, right), bound, objective)
        case Globally(operand=operand, bound=bound):  # G a = !(F !a)
            inside = _mask(mdp, progress, operand)
            return _complement(_until(mdp, progress, None, ~inside, bound, _opposite(objective)))
        case WeakUntil(left=left, right=right, bound=bound):  # a W b = !((a & !b) U (!a & !b))
            a, b = _mask(mdp, progress, left), _mask(mdp, progress, right)
            return _complement(_until(mdp, progress, a & ~b, ~a & ~b, bound,
                                      _opposite(objective)))
        case Release(left=left, right=right, bound=bound):  # a R b = !(!a U !b)
            a, b = _mask(mdp, progress, left), _mask(mdp, progress, right)
            return _complement(_until(mdp, progress, ~a, ~b, bound, _opposite(objective)))
        case Conditional():
            raise CheckError(CONDITIONAL_ON_MDP, path.span)
        case LtlPath():
            from veribattery.checker.mdp import ltl  # rare kinds of property: when met

            found = ltl.accepted_probability(mdp, path, partial(_mask, mdp, progress),
                                             negated=objective == "min", progress=progress)
            return _complement(found) if objective == "min" else found
        case RewardBounded(left=left, right=right, bound=bound):
            return reward_bounded_reach(mdp, reward_structure(mdp, path), reward_limit(bound),
                                        _mask(mdp, progress, left), _mask(mdp, progress, right),
                                        objective=objective, span=path.span, progress=progress)
    raise CheckError("this path formula is not supported on MDPs", path.span)


def _until(mdp: MDP, progress: Progress | None, remain: BoolArray | None, target: BoolArray,
           bound: TimeBound | TimeInterval | None, objective: Objective) -> Bounds:
    """``remain U target`` within its step interval."""
    if bound is None:
        return reach_probability(mdp, target, objective=objective, remain=remain,
                                 progress=progress).bounds
    if isinstance(bound, TimeInterval):
        low, high = step_bound(bound.low), step_bound(bound.high)
        if high < low:
            return Bounds.exact(np.zeros(mdp.num_states))
        return stepped.interval_reach_probability(mdp, target, low, high, objective=objective,
                                                  remain=remain, progress=progress).bounds
    steps = step_bound(bound.value)
    if bound.op in ("<=", "<"):
        steps -= bound.op == "<"
        if steps < 0:
            return Bounds.exact(np.zeros(mdp.num_states))
        return stepped.bounded_reach_probability(mdp, target, steps, objective=objective,
                                                 remain=remain, progress=progress).bounds
    if bound.op == "=":
        return stepped.interval_reach_probability(mdp, target, steps, steps,
                                                  objective=objective, remain=remain,
                                                  progress=progress).bounds
    steps += bound.op == ">"
    return stepped.later_reach_probability(mdp, target, steps, objective=objective,
                                           remain=remain, progress=progress).bounds


def _ctl(mdp: MDP, progress: Progress | None, quantifier: str,
         path: PathFormula) -> BoolArray:
    return quantified_states(mdp, quantifier, path, partial(_mask, mdp, progress))


def quantified_states(mdp: MDP, quantifier: str, path: PathFormula,
                      mask: Callable[[Expr], BoolArray]) -> BoolArray:
    """``A [path]``/``E [path]``: over every path of the MDP, whatever its choices (its
    state graph, as PRISM), by the DTMC side's graph algorithms.

    :param mask: the states satisfying an operand (in floats or exactly).
    """
    # Imported here: the DTMC graph kernels are needed by no other MDP formula.
    from veribattery.checker.formula import ctl
    from veribattery.checker.workspace import Workspace

    graph = ctl.state_pattern(mdp.transitions, mdp.choice_owner, mdp.num_states)
    if isinstance(path, LtlPath):
        from veribattery.checker.formula.ltl import ltl_quantified

        return ltl_quantified(graph, quantifier, path, mask)
    return ctl.quantified_path(graph, quantifier, path, mask, workspace=Workspace())


def _complement(b: Bounds) -> Bounds:
    """``1 - b`` with its certified interval, kept in [0, 1] (a probability's)."""
    one = Bounds.exact(np.ones(b.value.size))
    found = cast(Bounds, intervals.binary("-", one, b))
    return Bounds.around(found.value, np.maximum(found.lower, 0.0),
                         np.minimum(found.upper, 1.0))


def _reward(mdp: MDP, progress: Progress | None, op: RewardOp,
            objective: Objective) -> Bounds:
    """``Rmin``/``Rmax`` of a reward path in every state."""
    structure = reward_structure(mdp, op)
    path = op.path
    match path:
        case Reach(target=target):
            return reach_reward(mdp, structure.per_choice(mdp), _mask(mdp, progress, target),
                                objective=objective, progress=progress).bounds
        case Total():
            return total_reward(mdp, structure.per_choice(mdp), objective=objective,
                                progress=progress).bounds
        case Cumulative(bound=bound):
            return stepped.cumulative_reward(mdp, structure.per_choice(mdp), step_bound(bound),
                                             objective=objective, progress=progress).bounds
        case Instantaneous(time=time):
            return stepped.instantaneous_reward(mdp, structure.state, step_bound(time),
                                                objective=objective, progress=progress).bounds
        case ReachUntil(left=left, right=right):
            return cosafe.until_reward(mdp, structure.per_choice(mdp),
                                       _mask(mdp, progress, left),
                                       _mask(mdp, progress, right), objective=objective)
        case CosafeReach():
            from veribattery.checker.mdp import ltl

            return ltl.cosafe_reward(mdp, structure.per_choice(mdp), path,
                                     partial(_mask, mdp, progress), objective=objective,
                                     progress=progress)
        case ReachNext(target=target):
            return cosafe.next_reward(mdp, structure.per_choice(mdp),
                                      _mask(mdp, progress, target),
                                      objective=objective)
    raise CheckError("this reward formula is not supported on MDPs (F, U, X, C, C<=k, I=k "
                     "are)", path.span)


def _compound(mdp: MDP, progress: Progress | None, expr: Expr) -> Result:
    """Connectives, arithmetic and comparisons around operators, state by state."""
    match expr:
        case Unary(op=op, operand=operand):
            return intervals.unary(op, _values(mdp, progress, operand), expr.span)
        case Binary(op=op, left=left, right=right):
            return intervals.binary(op, _values(mdp, progress, left),
                                    _values(mdp, progress, right),
                                    expr.span)
        case Ite(cond=cond, then=then, otherwise=otherwise):
            return intervals.choose(_mask(mdp, progress, cond), _values(mdp, progress, then),
                                    _values(mdp, progress, otherwise))
        case Call(func=func, args=args):
            return intervals.call(func, [_values(mdp, progress, a) for a in args], expr.span)
    raise CheckError("this operator is not supported on MDPs", expr.span)


def _filter(mdp: MDP, progress: Progress | None, formula: Filter) -> filters.FilterOutcome:
    where = (np.ones(mdp.num_states, dtype=bool) if formula.states is None
             else _mask(mdp, progress, formula.states))
    values = _values(mdp, progress, formula.operand)
    return filters.apply_filter(formula.op, values, where, _states(mdp), mdp.variable_names,
                                formula.span)


def _filter_everywhere(mdp: MDP, progress: Progress | None, formula: Filter) -> Result:
    """A filter inside a formula: its one value in every state."""
    outcome = _filter(mdp, progress, formula)
    value = outcome.value
    if isinstance(value, tuple) or value is None:
        raise CheckError(f"filter({formula.op}, ...) has no single value here", formula.span)
    if isinstance(value, bool | np.bool_):
        return np.full(mdp.num_states, bool(value))
    low, high = outcome.interval or (float(value), float(value))
    n = mdp.num_states
    return Bounds(np.full(n, float(value)), np.full(n, low), np.full(n, high))


def _as_result(per_state: object) -> Result:
    if isinstance(per_state, Bounds):
        return per_state
    array = np.asarray(per_state)
    if array.dtype == np.bool_:
        return array
    return Bounds.exact(array.astype(np.float64))


def _leaf(mdp: MDP, expr: Expr) -> Result:
    """An operator-free state expression in every state."""
    for node in walk(expr):
        if isinstance(node, LabelRef) and node.name not in mdp.labels:
            raise CheckError(f'unknown label "{node.name}"', node.span)
    if isinstance(expr, BoolLit):
        return np.full(mdp.num_states, expr.value, dtype=bool)
    used = {node.name for node in walk(expr) if isinstance(node, Ident)}
    names = tuple(name for name in mdp.variable_names if name in used)
    columns = [mdp.variable_names.index(name) for name in names]
    rows = np.asarray(_states(mdp)[:, columns], dtype=np.int64)
    result = np.asarray(compile_expr(expr, names, dict(mdp.labels))(rows))
    result = np.broadcast_to(result, (mdp.num_states,)).copy()
    if result.dtype == np.bool_:
        return result
    return Bounds.exact(result.astype(np.float64))


def _states(mdp: MDP) -> IntArray:
    if mdp.states is None:
        return np.zeros((mdp.num_states, 0), dtype=np.int64)
    return mdp.states


