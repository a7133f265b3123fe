"""The PCTL recursion: formulas in, per-state arrays out, kernels doing the numbers.

State formulas become boolean masks (:func:`state_set`); ``P=?`` and ``R=?``
become per-state values (:func:`values`). Path formulas are reduced to the
kernels' vocabulary here, so that :mod:`~veribattery.checker.kernels` never sees
a node: ``F phi`` is ``true U phi``, ``G phi`` is ``1 - P(F !phi)``, ``U<k`` is
``U<=k-1`` and ``U>k`` is ``U>=k+1``.
"""

from __future__ import annotations

import functools
import math
import operator
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from typing import TypeAlias

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker import ctl, filters, intervals, kernels
from veribattery.checker.bounds import Bounds, escalated, required_precision
from veribattery.errors import CheckError, VeribatteryError
from veribattery.explore.compile import compile_expr
from veribattery.explore.dtmc import DTMC, RewardVectors
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    Conditional,
    ConditionalReach,
    Cumulative,
    DoubleLit,
    Eventually,
    Expr,
    Filter,
    Globally,
    Ident,
    Instantaneous,
    IntLit,
    Ite,
    LabelRef,
    LongRun,
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
from veribattery.lang.property_rules import STEPS_REWARD

_OPERATORS = (ProbOp, RewardOp, SteadyOp, Quantified, Filter)

Values: TypeAlias = FloatArray | BoolArray
#: What :func:`values` returns: certified numbers, or a state set.
Result: TypeAlias = Bounds | BoolArray

_CONNECTIVES: dict[str, Callable[[BoolArray, BoolArray], BoolArray]] = {
    "&": operator.and_,
    "|": operator.or_,
    "=>": lambda a, b: ~a | b,
    "<=>": operator.eq,
}

# ---------------------------------------------------------------------------
# Public entry points
# ---------------------------------------------------------------------------


def values(dtmc: DTMC, formula: Expr, focus_states: IntArray | None = None) -> Result:
    """Per-state value of *formula*: certified numbers for ``P=?``/``R=?``/``S=?``
    and expressions over them, booleans otherwise.

    :param dtmc: the model.
    :param formula: a property formula (constants substituted, labels inlined).
    :param focus_states: the only states whose bounds the caller reads, or None: a
        ``P=?``/``R=?`` operator's bounds may then be the trivial ones elsewhere
        (``kernels.until_probs``). Operands are always evaluated in every state.
    :raises CheckError: on unknown labels or reward structures, or unsupported nesting.
    """
    if isinstance(formula, ProbOp) and formula.op == "=?":
        return path_probs(dtmc, formula.path, focus_states)
    if isinstance(formula, RewardOp) and formula.op == "=?":
        return path_rewards(dtmc, formula, focus_states)
    if isinstance(formula, SteadyOp) and formula.op == "=?":
        from veribattery.checker import steady  # rare kinds of property: imported when met

        return steady.steady_probs(dtmc.transitions, state_set(dtmc, formula.operand))
    if isinstance(formula, Filter):
        return _filter_values(dtmc, formula)
    if _has_operator(formula):
        return _compound(dtmc, formula)
    leaf = _leaf(dtmc, formula)
    if leaf.dtype == np.bool_:
        return np.asarray(leaf, dtype=np.bool_)
    return Bounds.exact(np.asarray(leaf, dtype=np.float64))


def property_answer(dtmc: DTMC, formula: Expr, *,
                    initial_only: bool = False) -> filters.FilterOutcome:
    """The answer PRISM reports for a property: a filter's value, or PRISM's default
    filter -- ``forall`` initial states for a boolean, the value of the single
    initial state, or the ``range`` over several initial states.

    :param initial_only: the caller reads the answer, not the per-state values: then
        the per-state bounds of a property without a filter may be trivial away from
        the initial states (the answer's own are certified as always).
    :raises CheckError: when the model has no initial state, or a filter fails.
    """
    printed: tuple[str, ...] = ()
    if isinstance(formula, Filter):
        outcome = filter_outcome(dtmc, formula)
        if outcome.value is not None:
            return outcome
        per_state, printed = _as_result(outcome.values), outcome.printed
    elif isinstance(formula, ProbOp | RewardOp | SteadyOp) and formula.op != "=?":
        # Only the initial states' answers are reported: decide those, and mark
        # the other states true only where certified.
        per_state = _bounded_operator(dtmc, formula, must_decide=dtmc.initial)
    else:
        per_state = values(dtmc, formula, dtmc.initial if initial_only else None)
    if len(dtmc.initial) == 0:
        raise CheckError("the model has no initial state", formula.span)
    default = "forall" if not isinstance(per_state, Bounds) else (
        "state" if len(dtmc.initial) == 1 else "range")
    answer = filters.apply_filter(default, per_state, dtmc.initial_mask, dtmc.states,
                                  dtmc.variable_names, formula.span)
    return replace(answer, printed=printed)


def state_set(dtmc: DTMC, expr: Expr) -> BoolArray:
    """The states that satisfy the state formula *expr*, as a boolean mask.

    :param dtmc: the model.
    :param expr: a boolean state formula, possibly with bounded ``P``/``R`` operators.
    :raises CheckError: when *expr* is not boolean or nests operators unsupportedly.
    """
    if not _has_operator(expr):  # plain state predicate: evaluated whole, no recursion
        return _as_mask(_point(values(dtmc, expr)), expr)
    match expr:
        case ProbOp() | RewardOp() | SteadyOp():
            return _bounded_operator(dtmc, expr)
        case Quantified(quantifier=quantifier, path=path):
            return _ctl(dtmc, quantifier, path)
        case Unary(op="!", operand=operand):
            return ~state_set(dtmc, operand)
        case Binary(op="&" | "|" as op):  # a chain of thousands: a loop, not a recursion
            masks = (state_set(dtmc, operand) for operand in _chain(expr, op))
            return functools.reduce(_CONNECTIVES[op], masks)
        case Binary(op=op, left=left, right=right) if op in _CONNECTIVES:
            return _CONNECTIVES[op](state_set(dtmc, left), state_set(dtmc, right))
        case Ite(cond=cond, then=then, otherwise=otherwise) if _has_operator(expr):
            return np.where(state_set(dtmc, cond), state_set(dtmc, then),
                            state_set(dtmc, otherwise))
    return _as_mask(_point(values(dtmc, expr)), expr)


def _chain(expr: Binary, op: str) -> list[Expr]:
    """The operands of the chain of *op* (``&`` or ``|``) *expr* heads, left to right,
    however it is nested."""
    operands: list[Expr] = []
    stack: list[Expr] = [expr]
    while stack:
        node = stack.pop()
        if isinstance(node, Binary) and node.op == op:
            stack += (node.right, node.left)
        else:
            operands.append(node)
    return operands


def path_probs(dtmc: DTMC, path: PathFormula, focus_states: IntArray | None = None) -> Bounds:
    """Per-state probability of the path formula *path*, with certified bounds.

    ``G``, ``W`` and ``R`` are complements of an until (:meth:`Bounds.complement`).

    :param dtmc: the model.
    :param path: ``X``, ``U``, ``F`` or ``G``, optionally step-bounded.
    :param focus_states: as for :func:`values`.
    """
    focus = focus_states
    match path:
        case Next(operand=operand):
            return kernels.next_probs(dtmc.transitions, state_set(dtmc, operand))
        case Until(left=left, right=right, bound=bound):
            return _until(dtmc, state_set(dtmc, left), state_set(dtmc, right), bound, focus)
        case Eventually(operand=operand, bound=bound):
            return _until(dtmc, _everywhere(dtmc), state_set(dtmc, operand), bound, focus)
        case Globally(operand=operand, bound=bound):
            return _until(dtmc, _everywhere(dtmc), ~state_set(dtmc, operand), bound,
                          focus).complement()
        case WeakUntil(left=left, right=right, bound=bound):
            # a W b = !((a & !b) U (!a & !b)), bounds kept (as PRISM rewrites it).
            a, b = state_set(dtmc, left), state_set(dtmc, right)
            return _until(dtmc, a & ~b, ~a & ~b, bound, focus).complement()
        case Release(left=left, right=right, bound=bound):
            # a R b = !(!a U !b), bounds kept.
            a, b = state_set(dtmc, left), state_set(dtmc, right)
            return _until(dtmc, ~a, ~b, bound, focus).complement()
        case RewardBounded():
            return _reward_bounded_probs(dtmc, path)
        case Conditional():
            return _conditional_probs(dtmc, path)
    raise CheckError(f"unsupported path formula {type(path).__name__}", path.span)


def path_rewards(dtmc: DTMC, op: RewardOp, focus_states: IntArray | None = None) -> Bounds:
    """Per-state expected reward of the reward operator *op* (its bound is ignored), certified.

    :param dtmc: the model.
    :param op: ``R{..}`` over ``F``, ``C<=k`` or ``I=k``.
    :param focus_states: as for :func:`values`.
    """
    structure = _reward_structure(dtmc, op)
    path: RewardPath = op.path
    P = dtmc.transitions
    match path:
        case Reach(target=target):
            return kernels.reach_rewards(P, structure.total, state_set(dtmc, target),
                                         focus_states)
        case Cumulative(bound=bound):
            return kernels.cumulative_rewards(P, structure.total, _steps(bound))
        case Instantaneous(time=time):
            return kernels.instantaneous_rewards(P, structure.state, _steps(time))
        case Total():
            from veribattery.checker import steady

            return steady.total_rewards(P, structure.total)
        case LongRun():
            from veribattery.checker import steady

            return steady.long_run_rewards(P, structure.total)
        case ReachUntil(left=left, right=right):
            return _reach_until_rewards(dtmc, structure, left, right)
        case ReachNext(target=target):
            # Co-safe X phi is decided after one step: that step's reward, if sure.
            # Sure is graph analysis: no successor outside the target (positive
            # entries make the sum below 0 exactly where none is).
            sure = P @ (~state_set(dtmc, target)).astype(np.float64) == 0
            return Bounds.exact(np.where(sure, structure.total, np.inf))
        case ConditionalReach(target=target, condition=condition):
            from veribattery.checker import conditional

            return conditional.conditional_reach_reward_bounds(
                dtmc, structure, state_set(dtmc, target), state_set(dtmc, condition),
                _condition_name(condition), path.span, focus_states)
    raise CheckError(f"unsupported reward path {type(path).__name__}", path.span)


def prepare(dtmc: DTMC, formulas: Sequence[Expr]) -> None:
    """Let the unbounded queries among *formulas* share one linear system, whatever
    the order they are checked in.

    A ``P=? [ a U b ]`` whose unknown states lie inside those of an ``R=? [ F c ]``
    (and outside ``b``, inside ``a``) is solved on the latter's system (see
    :func:`kernels.shared_system`); when such a pair exists, the reward query's system
    is built first. Without reward queries, several untils share one system on the
    union of their unknowns where that is cheaper (:func:`kernels.prepare_untils`:
    a Fig. 6 point's ``P=? [ F "success" ]`` and the recharge cap's probability).
    Only operator-free operands are looked at (their masks are cheap); the pre-pass
    results are memoised, so checking repeats none of this work. The conditions of
    conditional properties are marked as needed in every state
    (:func:`kernels.need_whole`): a ``P=? [ F b ]`` among the properties then shares them.
    """
    P = dtmc.transitions
    for condition in (c for c in (_condition_set(dtmc, f) for f in formulas) if c is not None):
        kernels.need_whole(P, _everywhere(dtmc), condition)
    reach = [m for m in (_reach_target(dtmc, f) for f in formulas) if m is not None]
    untils = [u for u in (_until_operands(dtmc, f) for f in formulas) if u is not None]
    for target in reach if untils else ():
        unknowns = kernels.reach_unknowns(P, target)
        if any(_inside(kernels.until_unknowns(P, *until), unknowns) for until in untils):
            kernels.prepare_reach(P, target)
            return
    if len(untils) > 1 and not reach:
        kernels.prepare_untils(P, untils)


def _inside(query: tuple[BoolArray, BoolArray], unknowns: BoolArray) -> bool:
    """Whether a query's unknowns lie in *unknowns*, all of which satisfy its equations."""
    maybe, allowed = query
    return bool(maybe.any() and not np.any(maybe & ~unknowns)
                and not np.any(unknowns & ~allowed))


def _reach_target(dtmc: DTMC, formula: Expr) -> BoolArray | None:
    """The target of an ``R=? [ F a ]`` (or ``[ F a || F b ]``) with an operator-free *a*."""
    if not (isinstance(formula, RewardOp) and formula.op == "=?"):
        return None
    path = formula.path
    if isinstance(path, Reach | ConditionalReach) and not _has_operator(path.target):
        return _quiet_set(dtmc, path.target)
    return None


def _condition_set(dtmc: DTMC, formula: Expr) -> BoolArray | None:
    """The states *b* of an operator-free condition ``F b`` of a conditional ``P=?``/``R=?``."""
    if not (isinstance(formula, ProbOp | RewardOp) and formula.op == "=?"):
        return None
    path = formula.path
    if isinstance(path, ConditionalReach | Conditional) and not _has_operator(path.condition):
        return _quiet_set(dtmc, path.condition)
    return None


def _until_operands(dtmc: DTMC, formula: Expr) -> tuple[BoolArray, BoolArray] | None:
    """``(remain, target)`` of an unbounded ``P=? [ F b ]`` / ``[ a U b ]``, operator-free."""
    if not (isinstance(formula, ProbOp) and formula.op == "=?"):
        return None
    match formula.path:
        case Eventually(operand=operand, bound=None) if not _has_operator(operand):
            target = _quiet_set(dtmc, operand)
            return None if target is None else (_everywhere(dtmc), target)
        case Until(left=left, right=right, bound=None) if not (
                _has_operator(left) or _has_operator(right)):
            a, b = _quiet_set(dtmc, left), _quiet_set(dtmc, right)
            return None if a is None or b is None else (a, b)
    return None


def _quiet_set(dtmc: DTMC, expr: Expr) -> BoolArray | None:
    """:func:`state_set` of an operator-free *expr*, or None where it would fail
    (the check itself then reports the error)."""
    try:
        return state_set(dtmc, expr)
    except VeribatteryError:
        return None


# ---------------------------------------------------------------------------
# Storm's reward-bounded and conditional path formulas
# (kernels in checker/reward_bounded.py and checker/conditional.py)
# ---------------------------------------------------------------------------


def _reward_bounded_probs(dtmc: DTMC, path: RewardBounded) -> Bounds:
    """``U{"r"}<=T`` / ``F{"r"}<=T``, certified."""
    from veribattery.checker import reward_bounded

    structure = _reward_structure(dtmc, path)
    levels = reward_bounded.integer_rewards(dtmc, structure, path.span)
    return reward_bounded.reward_bounded_until_bounds(
        dtmc.transitions, state_set(dtmc, path.left), state_set(dtmc, path.right),
        levels, _reward_bound(path.bound))


def _conditional_probs(dtmc: DTMC, path: Conditional) -> Bounds:
    """``path || F b``: certified ratios for unbounded ``X F G U W R`` objectives, the
    product chain (range only, not certified) for step- and reward-bounded ones."""
    from veribattery.checker import conditional

    objective = path.path
    if any(_has_operator(operand) for operand in _operands(objective)):
        raise CheckError("P and R operators inside a conditional formula are not supported",
                         path.span)
    what = _condition_name(path.condition)
    given = conditional.condition_probs(dtmc.transitions, state_set(dtmc, path.condition))
    conditional.require_possible(given, dtmc.initial, what, path.span)
    reduced = _as_until(dtmc, objective)
    if reduced is not None:
        remain, target, negated = reduced
        found = conditional.until_given(dtmc.transitions, remain, target, given)
        return found.complement() if negated else found
    if isinstance(objective, Next):
        return conditional.next_given(dtmc.transitions, state_set(dtmc, objective.operand),
                                      given)
    return Bounds.uncertified(conditional.conditional_values(
        dtmc, given.states, lambda chain: path_probs(chain.dtmc, objective).value,
        what, path.span), 0.0, 1.0)


def _as_until(dtmc: DTMC, path: PathFormula) -> tuple[BoolArray, BoolArray, bool] | None:
    """An unbounded path formula as ``remain U target`` or its negation (None otherwise)."""
    match path:
        case Until(left=left, right=right, bound=None):
            return state_set(dtmc, left), state_set(dtmc, right), False
        case Eventually(operand=operand, bound=None):
            return _everywhere(dtmc), state_set(dtmc, operand), False
        case Globally(operand=operand, bound=None):
            return _everywhere(dtmc), ~state_set(dtmc, operand), True
        case WeakUntil(left=left, right=right, bound=None):
            a, b = state_set(dtmc, left), state_set(dtmc, right)
            return a & ~b, ~a & ~b, True
        case Release(left=left, right=right, bound=None):
            a, b = state_set(dtmc, left), state_set(dtmc, right)
            return ~a, ~b, True
    return None


def _reward_bound(bound: TimeBound) -> int:
    """The largest integer total reward that ``<=T`` / ``<T`` admits."""
    value = _number(bound.value)
    return math.floor(value) if bound.op == "<=" else math.ceil(value) - 1


def _condition_name(condition: Expr) -> str:
    """The condition as an error message names it."""
    if isinstance(condition, LabelRef):
        return f'F "{condition.name}"'
    return f"after || (at {condition.span})"


# ---------------------------------------------------------------------------
# Operators and bounds
# ---------------------------------------------------------------------------


def _bounded_operator(dtmc: DTMC, op: ProbOp | RewardOp | SteadyOp,
                      must_decide: IntArray | None = None) -> BoolArray:
    """``P~p [..]``, ``R~r [..]`` or ``S~p [..]`` as a mask: the value against the bound.

    Decided from the certified interval: a state whose interval straddles the
    bound is undecided. The property is refused rather than guessed when a state
    in *must_decide* (default: every state) is undecided; other undecided states
    are not in the mask (it holds only where certified).
    """
    if op.op == "=?" or op.bound is None:
        raise CheckError("a query (=?) cannot be used as a state formula", op.span)
    threshold = _number(op.bound)
    numbers, holds, undecided = _decide(dtmc, op, threshold, must_decide)
    if undecided.any():
        # Escalate: ask the kernels for exact (or as tight as reachable) bounds.
        with required_precision(0.0, 0.0):
            numbers, holds, undecided = _decide(dtmc, op, threshold, must_decide)
    if undecided.any():
        state = int(np.flatnonzero(undecided)[0])
        raise CheckError(
            f"precision not enough to decide {op.op} {threshold:g}: in {int(undecided.sum())} "
            f"state(s) the certified interval straddles the bound (state {state}: "
            f"[{numbers.lower[state]!r}, {numbers.upper[state]!r}])", op.span)
    return holds


def _decide(dtmc: DTMC, op: ProbOp | RewardOp | SteadyOp, threshold: float,
            must_decide: IntArray | None) -> tuple[Bounds, BoolArray, BoolArray]:
    """The operator's numbers, where the bound certainly holds, and where it is undecided."""
    numbers = values(dtmc, replace(op, op="=?", bound=None))
    assert isinstance(numbers, Bounds)  # a query always gives numbers
    holds, undecided = numbers.compare(op.op, threshold)
    if must_decide is not None:
        undecided = undecided & np.isin(np.arange(dtmc.num_states), must_decide)
    return numbers, holds, undecided


def _until(dtmc: DTMC, remain: BoolArray, target: BoolArray,
           bound: TimeBound | TimeInterval | None, focus_states: IntArray | None = None
           ) -> Bounds:
    """Dispatch ``remain U target`` to the kernel for its step interval."""
    P = dtmc.transitions
    if bound is None:
        return kernels.until_probs(P, remain, target, focus_states)
    low, high = _interval(bound)
    if high is not None and high < low:
        return Bounds.exact(np.zeros(dtmc.num_states))
    if low == 0:
        if high is None:
            return kernels.until_probs(P, remain, target, focus_states)
        return kernels.bounded_until_probs(P, remain, target, high)
    if high is None:
        return kernels.lower_bounded_until_probs(P, remain, target, low)
    return kernels.interval_until_probs(P, remain, target, low, high)


def _interval(bound: TimeBound | TimeInterval) -> tuple[int, int | None]:
    """The steps ``[low, high]`` (``high`` None: unbounded) at which the target counts."""
    if isinstance(bound, TimeInterval):
        return _steps(bound.low), _steps(bound.high)
    k = _steps(bound.value)
    match bound.op:
        case "<=":
            return 0, k
        case "<":
            return 0, k - 1
        case ">=":
            return k, None
        case ">":
            return k + 1, None
    return k, k


def _reward_structure(dtmc: DTMC, op: RewardOp | RewardBounded) -> RewardVectors:
    """The reward structure *op* names, or a CheckError that says where."""
    if op.reward == STEPS_REWARD:
        ones = np.ones(dtmc.num_states)
        return RewardVectors(None, ones, np.zeros(dtmc.num_states))
    try:
        structure = dtmc.reward(op.reward)
    except (KeyError, IndexError):
        key = "" if op.reward is None else f" {op.reward!r}"
        raise CheckError(f"the model has no reward structure{key}", op.span) from None
    if np.any(structure.state < 0) or np.any(structure.transition < 0):
        name = "" if structure.name is None else f' "{structure.name}"'
        raise CheckError(f"the reward structure{name} has negative rewards, which PRISM "
                         "does not allow", op.span)
    return structure


def _number(expr: Expr) -> float:
    """The value of a literal (constants are substituted before checking)."""
    match expr:
        case IntLit(value=value) | DoubleLit(value=value):
            return float(value)
        case Unary(op="-", operand=operand):
            return -_number(operand)
    raise CheckError("expected a numeric constant", expr.span)


def _steps(expr: Expr) -> int:
    """A step bound: a non-negative integer literal."""
    value = _number(expr)
    if value < 0 or value != int(value):
        raise CheckError(f"step bound must be a non-negative integer, not {value:g}",
                         expr.span)
    return int(value)


# ---------------------------------------------------------------------------
# Steady state, CTL, filters and expressions over operators
# ---------------------------------------------------------------------------


def _reach_until_rewards(dtmc: DTMC, structure: RewardVectors, left: Expr,
                         right: Expr) -> Bounds:
    """``R [a U b]``: the reward until *b*, infinite where ``a U b`` is not almost sure."""
    a, b = state_set(dtmc, left), state_set(dtmc, right)
    P = dtmc.transitions
    # Almost-sure is graph analysis (prob1), so the certified lower bound is exactly 1.
    sure = kernels.until_probs(P, a, b).lower >= 1.0
    rewards = kernels.reach_rewards(P, structure.total, b)
    infinite = np.full(dtmc.num_states, np.inf)
    return Bounds(np.where(sure, rewards.value, infinite), np.where(sure, rewards.lower, infinite),
                  np.where(sure, rewards.upper, infinite))


def _ctl(dtmc: DTMC, quantifier: str, path: PathFormula) -> BoolArray:
    """``A [path]`` or ``E [path]`` as a state set (unbounded operators only, as PRISM)."""
    bound = getattr(path, "bound", None)
    if bound is not None:
        raise CheckError("time-bounded temporal operators are not supported in CTL "
                         "(A [...] and E [...]), as in PRISM", path.span)
    ops = {Next: "X", Eventually: "F", Globally: "G", Until: "U", WeakUntil: "W",
           Release: "R"}
    if type(path) not in ops:
        raise CheckError("A [...] and E [...] take X, F, G, U, W or R, not a conditional (||) "
                         "formula", path.span)
    right = state_set(dtmc, _operands(path)[-1])
    left = state_set(dtmc, _operands(path)[0]) if len(_operands(path)) == 2 else right
    return ctl.quantified(dtmc.transitions, quantifier, ops[type(path)], left, right)


def _operands(path: PathFormula) -> tuple[Expr, ...]:
    if isinstance(path, Until | WeakUntil | Release | RewardBounded):
        return (path.left, path.right)
    if isinstance(path, Conditional):
        return (path.condition,)
    return (path.operand,)


def filter_outcome(dtmc: DTMC, node: Filter) -> filters.FilterOutcome:
    """The outcome of ``filter(op, prop, states)`` (value, per-state values, printout).

    :raises CheckError: for a filter over no states, or ``state`` over several.
    """
    where = _everywhere(dtmc) if node.states is None else state_set(dtmc, node.states)
    inner = values(dtmc, node.operand)
    return filters.apply_filter(node.op, inner, where, dtmc.states, dtmc.variable_names,
                                node.span)


def _filter_values(dtmc: DTMC, node: Filter) -> Result:
    """A filter inside an expression: its single value in every state (PRISM's semantics)."""
    outcome = filter_outcome(dtmc, node)
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


def _compound(dtmc: DTMC, expr: Expr) -> Result:
    """:func:`_compound_values`, retried at exact precision when a comparison of
    numbers is undecided by the intervals."""
    try:
        return _compound_values(dtmc, expr)
    except intervals.Undecided:
        if escalated():
            raise
    with required_precision(0.0, 0.0):
        return _compound_values(dtmc, expr)


def _compound_values(dtmc: DTMC, expr: Expr) -> Result:
    """Arithmetic, comparisons and functions over operator results, state by state,
    in interval arithmetic (:mod:`~veribattery.checker.intervals`)."""
    match expr:
        case Quantified() | ProbOp() | RewardOp() | SteadyOp():
            return state_set(dtmc, expr)
        case Unary(op="!", operand=operand):
            return ~state_set(dtmc, operand)
        case Unary(op=op, operand=operand):
            return intervals.unary(op, values(dtmc, operand), expr.span)
        case Binary(op=op, left=left, right=right) if op in _CONNECTIVES:
            return intervals.binary(op, state_set(dtmc, left), state_set(dtmc, right))
        case Binary(op=op, left=left, right=right):
            return intervals.binary(op, values(dtmc, left), values(dtmc, right), expr.span)
        case Ite(cond=cond, then=then, otherwise=otherwise):
            return intervals.choose(state_set(dtmc, cond), values(dtmc, then),
                                     values(dtmc, otherwise))
        case Call(func=func, args=args):
            return intervals.call(func, [values(dtmc, a) for a in args], expr.span)
    raise CheckError(f"cannot evaluate {type(expr).__name__} here", getattr(expr, "span", None))


# ---------------------------------------------------------------------------
# Leaves: labels and operator-free state expressions
# ---------------------------------------------------------------------------


def _leaf(dtmc: DTMC, expr: Expr) -> Values:
    """Evaluate an operator-free state expression in every state."""
    for ref in _labels_in(expr):
        if ref.name not in dtmc.labels:
            raise CheckError(f'unknown label "{ref.name}"', ref.span)
    match expr:
        case LabelRef(name=name):
            return np.asarray(dtmc.labels[name], dtype=bool)
        case BoolLit(value=value):
            return np.full(dtmc.num_states, value, dtype=bool)
    return _compiled(dtmc, expr)


def _compiled(dtmc: DTMC, expr: Expr) -> Values:
    """Evaluate *expr* with the builder's expression compiler, on int64 copies of the
    variables it reads (the state table may be stored narrower: :meth:`DTMC.compact`)."""
    used = {node.name for node in walk(expr) if isinstance(node, Ident)}
    names = tuple(name for name in dtmc.variable_names if name in used)
    columns = [dtmc.variable_names.index(name) for name in names]
    states = np.asarray(dtmc.states[:, columns], dtype=np.int64)
    result = np.asarray(compile_expr(expr, names, dtmc.labels)(states))
    del states
    result = np.broadcast_to(result, (dtmc.num_states,)).copy()
    return result if result.dtype == np.bool_ else result.astype(np.float64)


def _as_mask(result: Values, expr: Expr) -> BoolArray:
    """A leaf's values as a mask; boolean variables arrive as 0/1 integers."""
    if result.dtype == np.bool_:
        return np.asarray(result, dtype=np.bool_)
    if np.all((result == 0) | (result == 1)):
        return np.asarray(result == 1, dtype=np.bool_)
    raise CheckError("expected a boolean state formula", expr.span)


def _as_result(per_state: Bounds | Values) -> Result:
    """A filter's per-state values as a result (numbers without bounds: exact)."""
    if isinstance(per_state, Bounds):
        return per_state
    if per_state.dtype == np.bool_:
        return np.asarray(per_state, dtype=np.bool_)
    return Bounds.exact(np.asarray(per_state, dtype=np.float64))


def _point(result: Result) -> Values:
    """The point values of a result (a mask stays a mask)."""
    return result.value if isinstance(result, Bounds) else result


def _everywhere(dtmc: DTMC) -> BoolArray:
    return np.ones(dtmc.num_states, dtype=bool)


def _has_operator(expr: Expr) -> bool:
    """Whether *expr* needs the checker: an operator, a filter or ``round`` occurs in it."""
    return any(isinstance(node, _OPERATORS) or (isinstance(node, Call) and node.func == "round")
               for node in walk(expr))


def _labels_in(expr: Expr) -> Iterator[LabelRef]:
    """Every label reference in *expr*."""
    return (node for node in walk(expr) if isinstance(node, LabelRef))
