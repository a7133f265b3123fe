"""The PCTL recursion: formulas in, per-state arrays out, kernels doing the numbers.

State formulas become boolean masks (:func:`state_set`); ``P=?`` and ``R=?``
become per-state values (:func:`values`). Path formulas are reduced to the
kernels' vocabulary here, so that :mod:`~veribattery.checker.kernels.until` never sees
a node: ``F phi`` is ``true U phi``, ``G phi`` is ``1 - P(F !phi)``, ``U<k`` is
``U<=k-1`` and ``U>k`` is ``U>=k+1``.
"""

from __future__ import annotations

import functools
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.checker import kernels
from veribattery.checker.certify.bounds import Bounds, escalated, required_precision
from veribattery.checker.formula import ctl, filters, intervals
from veribattery.checker.formula.leaves import (
    CONNECTIVES,
    _as_result,
    _condition_name,
    _everywhere,
    _operands,
    _point,
    _reward_structure,
    as_mask,
    has_operator,
    leaf_values,
    literal_number,
    reward_limit,
    step_bound,
    step_interval,
)
from veribattery.errors import CheckError
from veribattery.explore.dtmc import DTMC, RewardVectors
from veribattery.lang.expressions import operand_chain
from veribattery.lang.nodes import (
    Binary,
    Call,
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
    Quantified,
    Reach,
    ReachNext,
    ReachUntil,
    Release,
    RewardBounded,
    RewardOp,
    RewardPath,
    SteadyOp,
    TimeBound,
    TimeInterval,
    Total,
    Unary,
    Until,
    WeakUntil,
)

if TYPE_CHECKING:
    from veribattery.checker.formula.leaves import Result
    from veribattery.checker.result import Keep
    from veribattery.checker.workspace import Workspace


# ---------------------------------------------------------------------------
# Public entry points
# ---------------------------------------------------------------------------


def values(dtmc: DTMC, workspace: Workspace, formula: Expr,
           focus_states: IntArray | None = None) -> Result:
    """Per-state value of *formula*: certified numbers for ``P=?``/``R=?``/``S=?``
    and expressions over them, booleans otherwise.

    :param dtmc: the model.
    :param workspace: where graph searches, linear systems and results are kept for the
        later queries of its owner (:class:`~veribattery.checker.workspace.Workspace`).
    :param formula: a property formula (constants substituted, labels inlined).
    :param focus_states: the only states whose bounds the caller reads, or None: a
        ``P=?``/``R=?`` operator's bounds may then be the trivial ones elsewhere
        (``kernels.until_probs``). Operands are always evaluated in every state.
    :raises CheckError: on unknown labels or reward structures, or unsupported nesting.
    """
    if isinstance(formula, ProbOp) and formula.op == "=?":
        return path_probs(dtmc, workspace, formula.path, focus_states)
    if isinstance(formula, RewardOp) and formula.op == "=?":
        return path_rewards(dtmc, workspace, formula, focus_states)
    if isinstance(formula, SteadyOp) and formula.op == "=?":
        from veribattery.checker.kernels import steady  # rare kinds of property: when met

        target = state_set(dtmc, workspace, formula.operand)
        return steady.steady_probs(dtmc.transitions, target, workspace=workspace)
    if isinstance(formula, Filter):
        return _filter_values(dtmc, workspace, formula)
    if has_operator(formula):
        return _compound(dtmc, workspace, formula)
    leaf = leaf_values(dtmc, formula)
    if leaf.dtype == np.bool_:
        return np.asarray(leaf, dtype=np.bool_)
    return Bounds.exact(np.asarray(leaf, dtype=np.float64))


def property_answer(dtmc: DTMC, workspace: Workspace, formula: Expr, *,
                    keep: Keep = "states") -> filters.FilterOutcome:
    """The answer PRISM reports for a property: a filter's value, or PRISM's default
    filter -- ``forall`` initial states for a boolean, the value of the single
    initial state, or the ``range`` over several initial states.

    :param keep: ``"answers"``: the caller reads the answer, not the per-state values: then
        the per-state bounds of a property without a filter may be trivial away from
        the initial states (the answer's own are certified as always).
    :raises CheckError: when the model has no initial state, or a filter fails.
    """
    printed: tuple[str, ...] = ()
    if isinstance(formula, Filter):
        outcome = filter_outcome(dtmc, workspace, formula)
        if outcome.value is not None:
            return outcome
        per_state, printed = _as_result(outcome.values), outcome.printed
    elif isinstance(formula, ProbOp | RewardOp | SteadyOp) and formula.op != "=?":
        # Only the initial states' answers are reported: decide those, and mark
        # the other states true only where certified.
        per_state = _bounded_operator(dtmc, workspace, formula, must_decide=dtmc.initial)
    else:
        per_state = values(dtmc, workspace, formula, dtmc.initial if keep == "answers" else None)
    if len(dtmc.initial) == 0:
        raise CheckError("the model has no initial state", formula.span)
    default = "forall" if not isinstance(per_state, Bounds) else (
        "state" if len(dtmc.initial) == 1 else "range")
    answer = filters.apply_filter(default, per_state, dtmc.initial_mask, dtmc.states,
                                  dtmc.variable_names, formula.span)
    return replace(answer, printed=printed)


def state_set(dtmc: DTMC, workspace: Workspace, expr: Expr) -> BoolArray:
    """The states that satisfy the state formula *expr*, as a boolean mask.

    :param dtmc: the model.
    :param expr: a boolean state formula, possibly with bounded ``P``/``R`` operators.
    :raises CheckError: when *expr* is not boolean or nests operators unsupportedly.
    """
    if not has_operator(expr):  # plain state predicate: evaluated whole, no recursion
        return as_mask(_point(values(dtmc, workspace, expr)), expr)
    match expr:
        case ProbOp() | RewardOp() | SteadyOp():
            return _bounded_operator(dtmc, workspace, expr)
        case Quantified(quantifier=quantifier, path=path):
            return _ctl(dtmc, workspace, quantifier, path)
        case Unary(op="!", operand=operand):
            return ~state_set(dtmc, workspace, operand)
        case Binary(op="&" | "|" as op):  # a chain of thousands: a loop, not a recursion
            masks = (state_set(dtmc, workspace, operand) for operand in operand_chain(expr, op))
            return functools.reduce(CONNECTIVES[op], masks)
        case Binary(op=op, left=left, right=right) if op in CONNECTIVES:
            return CONNECTIVES[op](state_set(dtmc, workspace, left),
                                    state_set(dtmc, workspace, right))
        case Ite(cond=cond, then=then, otherwise=otherwise) if has_operator(expr):
            return np.where(state_set(dtmc, workspace, cond), state_set(dtmc, workspace, then),
                            state_set(dtmc, workspace, otherwise))
    return as_mask(_point(values(dtmc, workspace, expr)), expr)


def path_probs(dtmc: DTMC, workspace: Workspace, path: PathFormula,
               focus_states: IntArray | None = None) -> Bounds:
    """Per-state probability of the path formula *path*, with certified bounds.

    ``G``, ``W`` and ``R`` are complements of an until (:meth:`Bounds.complement`).

    :param dtmc: the model.
    :param path: ``X``, ``U``, ``F`` or ``G``, optionally step-bounded.
    :param focus_states: as for :func:`values`.
    """
    focus = focus_states
    match path:
        case Next(operand=operand):
            return kernels.next_probs(dtmc.transitions, state_set(dtmc, workspace, operand))
        case Until(left=left, right=right, bound=bound):
            a, b = state_set(dtmc, workspace, left), state_set(dtmc, workspace, right)
            return _until(dtmc, workspace, a, b, bound, focus)
        case Eventually(operand=operand, bound=bound):
            target = state_set(dtmc, workspace, operand)
            return _until(dtmc, workspace, _everywhere(dtmc), target, bound, focus)
        case Globally(operand=operand, bound=bound):
            escape = ~state_set(dtmc, workspace, operand)
            return _until(dtmc, workspace, _everywhere(dtmc), escape, bound, focus).complement()
        case WeakUntil(left=left, right=right, bound=bound):
            # a W b = !((a & !b) U (!a & !b)), bounds kept (as PRISM rewrites it).
            a, b = state_set(dtmc, workspace, left), state_set(dtmc, workspace, right)
            return _until(dtmc, workspace, a & ~b, ~a & ~b, bound, focus).complement()
        case Release(left=left, right=right, bound=bound):
            # a R b = !(!a U !b), bounds kept.
            a, b = state_set(dtmc, workspace, left), state_set(dtmc, workspace, right)
            return _until(dtmc, workspace, ~a, ~b, bound, focus).complement()
        case RewardBounded():
            return _reward_bounded_probs(dtmc, workspace, path)
        case Conditional():
            return _conditional_probs(dtmc, workspace, path)
        case LtlPath():
            from veribattery.checker.formula import ltl  # rare kinds of property: when met

            return ltl.ltl_probs(dtmc.transitions, path, functools.partial(
                state_set, dtmc, workspace), workspace=workspace)
    raise CheckError(f"unsupported path formula {type(path).__name__}", path.span)


def path_rewards(dtmc: DTMC, workspace: Workspace, op: RewardOp,
                 focus_states: IntArray | None = None) -> Bounds:
    """Per-state expected reward of the reward operator *op* (its bound is ignored), certified.

    :param dtmc: the model.
    :param op: ``R{..}`` over ``F``, ``C<=k`` or ``I=k``.
    :param focus_states: as for :func:`values`.
    """
    structure = _reward_structure(dtmc, op)
    found = _expected_rewards(dtmc, workspace, op.path, structure, focus_states)
    per_step = structure.state if isinstance(op.path, Instantaneous) else structure.total
    return kernels.reward_free_zeros(dtmc.transitions, per_step, found, workspace=workspace)


def _expected_rewards(dtmc: DTMC, workspace: Workspace, path: RewardPath,
                      structure: RewardVectors, focus_states: IntArray | None) -> Bounds:
    P = dtmc.transitions
    match path:
        case Reach(target=target):
            return kernels.reach_rewards(P, structure.total, state_set(dtmc, workspace, target),
                                         focus_states, workspace=workspace)
        case Cumulative(bound=bound):
            return kernels.cumulative_rewards(P, structure.total, step_bound(bound),
                                              progress=workspace.monitor)
        case Instantaneous(time=time):
            return kernels.instantaneous_rewards(P, structure.state, step_bound(time),
                                                 progress=workspace.monitor)
        case Total():
            from veribattery.checker.kernels import steady

            return steady.total_rewards(P, structure.total, workspace=workspace)
        case LongRun():
            from veribattery.checker.kernels import steady

            return steady.long_run_rewards(P, structure.total, workspace=workspace)
        case ReachUntil(left=left, right=right):
            return _reach_until_rewards(dtmc, workspace, structure, left, right)
        case ReachNext(target=target):
            # Co-safe X phi is decided after one step: that step's reward, if sure.
            # Sure is graph analysis: no successor outside the target (positive
            # entries make the sum below 0 exactly where none is).
            sure = P @ (~state_set(dtmc, workspace, target)).astype(np.float64) == 0
            return Bounds.exact(np.where(sure, structure.total, np.inf))
        case ConditionalReach(target=target, condition=condition):
            from veribattery.checker.kernels import conditional

            return conditional.conditional_reach_reward_bounds(
                dtmc, structure, state_set(dtmc, workspace, target),
                state_set(dtmc, workspace, condition), _condition_name(condition), path.span,
                focus_states, workspace=workspace)
        case CosafeReach():
            from veribattery.checker.formula import ltl

            return ltl.cosafe_rewards(P, structure.total, path, functools.partial(
                state_set, dtmc, workspace), workspace=workspace)
    raise CheckError(f"unsupported reward path {type(path).__name__}", path.span)


# ---------------------------------------------------------------------------
# Storm's reward-bounded and conditional path formulas
# (kernels in checker/kernels/reward_bounded.py and checker/kernels/conditional.py)
# ---------------------------------------------------------------------------


def _reward_bounded_probs(dtmc: DTMC, workspace: Workspace, path: RewardBounded) -> Bounds:
    """``U{"r"}<=T`` / ``F{"r"}<=T`` (and ``>=B``), certified."""
    from veribattery.checker.kernels import reward_bounded

    structure = _reward_structure(dtmc, path)
    levels = reward_bounded.integer_rewards(dtmc, structure, path.span)
    remain, target = state_set(dtmc, workspace, path.left), state_set(dtmc, workspace, path.right)
    limit = reward_limit(path.bound)
    if limit.gather:
        from veribattery.checker.kernels.reward_layers import gathered_until_bounds

        return gathered_until_bounds(dtmc.transitions, remain, target, levels, limit.total,
                                     path.span, workspace=workspace)
    return reward_bounded.reward_bounded_until_bounds(dtmc.transitions, remain, target, levels,
                                                      limit.total, workspace=workspace)


def _conditional_probs(dtmc: DTMC, workspace: Workspace, path: Conditional) -> Bounds:
    """``path || F b``: certified ratios for unbounded ``X F G U W R`` objectives, the
    product chain (range only, not certified) for step- and reward-bounded ones."""
    from veribattery.checker.kernels import conditional

    objective = path.path
    if any(has_operator(operand) for operand in _operands(objective)):
        raise CheckError("P and R operators inside a conditional formula are not supported",
                         path.span)
    what = _condition_name(path.condition)
    given = conditional.condition_probs(dtmc.transitions,
                                        state_set(dtmc, workspace, path.condition),
                                        workspace=workspace)
    conditional.require_possible(given, dtmc.initial, what, path.span)
    reduced = _as_until(dtmc, workspace, objective)
    if reduced is not None:
        remain, target, negated = reduced
        found = conditional.until_given(dtmc.transitions, remain, target, given,
                                        workspace=workspace)
        return found.complement() if negated else found
    if isinstance(objective, Next):
        return conditional.next_given(dtmc.transitions,
                                      state_set(dtmc, workspace, objective.operand), given)
    return Bounds.uncertified(conditional.conditional_values(
        dtmc, given.states, lambda chain: path_probs(chain.dtmc, workspace, objective).value,
        what, path.span, workspace=workspace), 0.0, 1.0)


def _as_until(dtmc: DTMC, workspace: Workspace, path: PathFormula
              ) -> tuple[BoolArray, BoolArray, bool] | None:
    """An unbounded path formula as ``remain U target`` or its negation (None otherwise)."""
    match path:
        case Until(left=left, right=right, bound=None):
            return state_set(dtmc, workspace, left), state_set(dtmc, workspace, right), False
        case Eventually(operand=operand, bound=None):
            return _everywhere(dtmc), state_set(dtmc, workspace, operand), False
        case Globally(operand=operand, bound=None):
            return _everywhere(dtmc), ~state_set(dtmc, workspace, operand), True
        case WeakUntil(left=left, right=right, bound=None):
            a, b = state_set(dtmc, workspace, left), state_set(dtmc, workspace, right)
            return a & ~b, ~a & ~b, True
        case Release(left=left, right=right, bound=None):
            a, b = state_set(dtmc, workspace, left), state_set(dtmc, workspace, right)
            return ~a, ~b, True
    return None


# ---------------------------------------------------------------------------
# Operators and bounds
# ---------------------------------------------------------------------------


def _bounded_operator(dtmc: DTMC, workspace: Workspace, op: ProbOp | RewardOp | SteadyOp,
                      must_decide: IntArray | None = None) -> BoolArray:
    """``P~p [..]``, ``R~r [..]`` or ``S~p [..]`` as a mask: the value against the bound.

    Decided from the certified interval: a state whose interval straddles the
    bound is undecided. The property is refused rather than guessed when a state
    in *must_decide* (default: every state) is undecided; other undecided states
    are not in the mask (it holds only where certified).
    """
    if op.op == "=?" or op.bound is None:
        raise CheckError("a query (=?) cannot be used as a state formula", op.span)
    threshold = literal_number(op.bound)
    numbers, holds, undecided = _decide(dtmc, workspace, op, threshold, must_decide)
    if undecided.any():
        # Escalate: ask the kernels for exact (or as tight as reachable) bounds.
        with required_precision(0.0, 0.0):
            numbers, holds, undecided = _decide(dtmc, workspace, op, threshold, must_decide)
    if undecided.any():
        raise intervals.Undecided.straddled(op.op, threshold, numbers, undecided, op.span)
    return holds


def _decide(dtmc: DTMC, workspace: Workspace, op: ProbOp | RewardOp | SteadyOp, threshold: float,
            must_decide: IntArray | None) -> tuple[Bounds, BoolArray, BoolArray]:
    """The operator's numbers, where the bound certainly holds, and where it is undecided."""
    numbers = values(dtmc, workspace, replace(op, op="=?", bound=None))
    assert isinstance(numbers, Bounds)  # a query always gives numbers
    holds, undecided = numbers.compare(op.op, threshold)
    if must_decide is not None:
        undecided = undecided & np.isin(np.arange(dtmc.num_states), must_decide)
    return numbers, holds, undecided


def _until(dtmc: DTMC, workspace: Workspace, remain: BoolArray, target: BoolArray,
           bound: TimeBound | TimeInterval | None, focus_states: IntArray | None = None
           ) -> Bounds:
    """Dispatch ``remain U target`` to the kernel for its step interval."""
    P = dtmc.transitions
    if bound is None:
        return kernels.until_probs(P, remain, target, focus_states, workspace=workspace)
    low, high = step_interval(bound)
    if high is not None and high < low:
        return Bounds.exact(np.zeros(dtmc.num_states))
    if low == 0:
        if high is None:
            return kernels.until_probs(P, remain, target, focus_states, workspace=workspace)
        return kernels.bounded_until_probs(P, remain, target, high, progress=workspace.monitor,
                                           workspace=workspace)
    if high is None:
        return kernels.lower_bounded_until_probs(P, remain, target, low, workspace=workspace)
    return kernels.interval_until_probs(P, remain, target, low, high,
                                        progress=workspace.monitor, workspace=workspace)


# ---------------------------------------------------------------------------
# Steady state, CTL, filters and expressions over operators
# ---------------------------------------------------------------------------


def _reach_until_rewards(dtmc: DTMC, workspace: Workspace, structure: RewardVectors, left: Expr,
                         right: Expr) -> Bounds:
    """``R [a U b]``: the reward until *b*, infinite where ``a U b`` is not almost sure."""
    a, b = state_set(dtmc, workspace, left), state_set(dtmc, workspace, right)
    P = dtmc.transitions
    # Almost-sure is graph analysis (prob1), so the certified lower bound is exactly 1.
    sure = kernels.until_probs(P, a, b, workspace=workspace).lower >= 1.0
    rewards = kernels.reach_rewards(P, structure.total, b, workspace=workspace)
    infinite = np.full(dtmc.num_states, np.inf)
    return Bounds(np.where(sure, rewards.value, infinite), np.where(sure, rewards.lower, infinite),
                  np.where(sure, rewards.upper, infinite))


def _ctl(dtmc: DTMC, workspace: Workspace, quantifier: str, path: PathFormula) -> BoolArray:
    """``A [path]`` or ``E [path]`` as a state set (unbounded operators only, as PRISM)."""
    if isinstance(path, LtlPath):
        from veribattery.checker.formula import ltl

        return ltl.ltl_quantified(dtmc.transitions, quantifier, path,
                                  functools.partial(state_set, dtmc, workspace))
    return ctl.quantified_path(dtmc.transitions, quantifier, path,
                               functools.partial(state_set, dtmc, workspace), workspace=workspace)


def filter_outcome(dtmc: DTMC, workspace: Workspace, node: Filter) -> filters.FilterOutcome:
    """The outcome of ``filter(op, prop, states)`` (value, per-state values, printout).

    :raises CheckError: for a filter over no states, or ``state`` over several.
    """
    where = _everywhere(dtmc) if node.states is None else state_set(dtmc, workspace, node.states)
    inner = values(dtmc, workspace, node.operand)
    return filters.apply_filter(node.op, inner, where, dtmc.states, dtmc.variable_names,
                                node.span)


def _filter_values(dtmc: DTMC, workspace: Workspace, node: Filter) -> Result:
    """A filter inside an expression: its single value in every state (PRISM's semantics)."""
    outcome = filter_outcome(dtmc, workspace, node)
    if outcome.value is None or isinstance(outcome.value, tuple):
        if isinstance(outcome.value, tuple):
            raise CheckError("filter(range, ...) gives an interval, which cannot be used "
                             "inside an expression", node.span)
        return _as_result(outcome.values)
    value = outcome.value
    if isinstance(value, bool):
        return np.full(dtmc.num_states, value, dtype=np.bool_)
    low, high = outcome.interval or (value, value)
    return Bounds(*(np.full(dtmc.num_states, float(v)) for v in (value, low, high)))


def _compound(dtmc: DTMC, workspace: Workspace, expr: Expr) -> Result:
    """:func:`_compound_values`, retried at exact precision when a comparison of
    numbers is undecided by the intervals."""
    try:
        return _compound_values(dtmc, workspace, expr)
    except intervals.Undecided:
        if escalated():
            raise
    with required_precision(0.0, 0.0):
        return _compound_values(dtmc, workspace, expr)


def _compound_values(dtmc: DTMC, workspace: Workspace, expr: Expr) -> Result:
    """Arithmetic, comparisons and functions over operator results, state by state,
    in interval arithmetic (:mod:`~veribattery.checker.formula.intervals`)."""
    match expr:
        case Quantified() | ProbOp() | RewardOp() | SteadyOp():
            return state_set(dtmc, workspace, expr)
        case Unary(op="!", operand=operand):
            return ~state_set(dtmc, workspace, operand)
        case Unary(op=op, operand=operand):
            return intervals.unary(op, values(dtmc, workspace, operand), expr.span)
        case Binary(op=op, left=left, right=right) if op in CONNECTIVES:
            return intervals.binary(op, state_set(dtmc, workspace, left),
                                    state_set(dtmc, workspace, right))
        case Binary(op=op, left=left, right=right):
            return intervals.binary(op, values(dtmc, workspace, left),
                                    values(dtmc, workspace, right), expr.span)
        case Ite(cond=cond, then=then, otherwise=otherwise):
            return intervals.choose(state_set(dtmc, workspace, cond), values(dtmc, workspace, then),
                                     values(dtmc, workspace, otherwise))
        case Call(func=func, args=args):
            return intervals.call(func, [values(dtmc, workspace, a) for a in args], expr.span)
    raise CheckError(f"cannot evaluate {type(expr).__name__} here", getattr(expr, "span", None))
