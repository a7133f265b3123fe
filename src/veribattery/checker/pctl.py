"""The PCTL recursion: formulas in, per-state arrays out, kernels doing the numbers.

State formulas become boolean masks (:func:`state_set`); ``P=?`` and ``R=?``
become per-state values (:func:`values`). Path formulas are reduced to the
kernels' vocabulary here, so that :mod:`~veribattery.checker.kernels` never sees
a node: ``F phi`` is ``true U phi``, ``G phi`` is ``1 - P(F !phi)``, ``U<k`` is
``U<=k-1`` and ``U>k`` is ``U>=k+1``.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Iterator
from typing import TypeAlias

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker import conditional, kernels, reward_bounded
from veribattery.checker.bounds import Bounds, required_precision
from veribattery.errors import CheckError
from veribattery.explore.compile import compile_expr
from veribattery.explore.dtmc import DTMC, RewardVectors
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
    Globally,
    Instantaneous,
    IntLit,
    Ite,
    LabelRef,
    Next,
    PathFormula,
    ProbOp,
    Reach,
    RewardBounded,
    RewardOp,
    RewardPath,
    TimeBound,
    Unary,
    Until,
)

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


def values(dtmc: DTMC, formula: Expr) -> Result:
    """Per-state value of *formula*: certified numbers for ``P=?``/``R=?``, booleans otherwise.

    :param dtmc: the model.
    :param formula: a property formula (constants substituted, labels inlined).
    :raises CheckError: on unknown labels or reward structures, or unsupported nesting.
    """
    if isinstance(formula, ProbOp) and formula.op == "=?":
        return path_probs(dtmc, formula.path)
    if isinstance(formula, RewardOp) and formula.op == "=?":
        return path_rewards(dtmc, formula)
    if isinstance(formula, ProbOp | RewardOp):
        # Only the initial states' answers are reported: decide those, and mark
        # the other states true only where certified.
        return _bounded_operator(dtmc, formula, must_decide=dtmc.initial)
    if _has_operator(formula):
        return state_set(dtmc, formula)
    leaf = _leaf(dtmc, formula)
    if leaf.dtype == np.bool_:
        return np.asarray(leaf, dtype=np.bool_)
    return Bounds.exact(np.asarray(leaf, dtype=np.float64))


def state_set(dtmc: DTMC, expr: Expr) -> BoolArray:
    """The states that satisfy the state formula *expr*, as a boolean mask.

    :param dtmc: the model.
    :param expr: a boolean state formula, possibly with bounded ``P``/``R`` operators.
    :raises CheckError: when *expr* is not boolean or nests operators unsupportedly.
    """
    match expr:
        case ProbOp() | RewardOp():
            return _bounded_operator(dtmc, expr)
        case Unary(op="!", operand=operand):
            return ~state_set(dtmc, operand)
        case Binary(op=op, left=left, right=right) if op in _CONNECTIVES:
            return _CONNECTIVES[op](state_set(dtmc, left), state_set(dtmc, right))
        case Ite(cond=cond, then=then, otherwise=otherwise) if _has_operator(expr):
            return np.where(state_set(dtmc, cond), state_set(dtmc, then),
                            state_set(dtmc, otherwise))
    if _has_operator(expr):
        raise CheckError("P and R operators may only be combined with ! & | => <=> "
                         "and ?:", expr.span)
    return _as_mask(_leaf(dtmc, expr), expr)


def path_probs(dtmc: DTMC, path: PathFormula) -> Bounds:
    """Per-state probability of the path formula *path*, with certified bounds.

    :param dtmc: the model.
    :param path: ``X``, ``U``, ``F`` or ``G``, optionally step-bounded.
    """
    match path:
        case Next(operand=operand):
            return kernels.next_probs(dtmc.transitions, state_set(dtmc, operand))
        case Until(left=left, right=right, bound=bound):
            return _until(dtmc, state_set(dtmc, left), state_set(dtmc, right), bound)
        case Eventually(operand=operand, bound=bound):
            return _until(dtmc, _everywhere(dtmc), state_set(dtmc, operand), bound)
        case Globally(operand=operand, bound=bound):
            return _until(dtmc, _everywhere(dtmc), ~state_set(dtmc, operand), bound).complement()
        case RewardBounded() | Conditional():
            return Bounds.uncertified(_storm_path_probs(dtmc, path), 0.0, 1.0)
    raise CheckError(f"unsupported path formula {type(path).__name__}", path.span)


def path_rewards(dtmc: DTMC, op: RewardOp) -> Bounds:
    """Per-state expected reward of the reward operator *op* (its bound is ignored), certified.

    :param dtmc: the model.
    :param op: ``R{..}`` over ``F``, ``C<=k`` or ``I=k``.
    """
    structure = _reward_structure(dtmc, op)
    path: RewardPath = op.path
    P = dtmc.transitions
    match path:
        case Reach(target=target):
            return kernels.reach_rewards(P, structure.total, state_set(dtmc, target))
        case Cumulative(bound=bound):
            return kernels.cumulative_rewards(P, structure.total, _steps(bound))
        case Instantaneous(time=time):
            return kernels.instantaneous_rewards(P, structure.state, _steps(time))
        case ConditionalReach(target=target, condition=condition):
            return Bounds.uncertified(conditional.conditional_reach_rewards(
                dtmc, structure, state_set(dtmc, target), state_set(dtmc, condition),
                _condition_name(condition), path.span), 0.0, np.inf)
    raise CheckError(f"unsupported reward path {type(path).__name__}", path.span)


# ---------------------------------------------------------------------------
# Storm's reward-bounded and conditional path formulas
# (kernels in checker/reward_bounded.py and checker/conditional.py)
# ---------------------------------------------------------------------------


def _storm_path_probs(dtmc: DTMC, path: RewardBounded | Conditional) -> FloatArray:
    """``U{"r"}<=T`` / ``F{"r"}<=T``, and ``path || F b``."""
    if isinstance(path, RewardBounded):
        structure = _reward_structure(dtmc, path)
        levels = reward_bounded.integer_rewards(dtmc, structure, path.span)
        return reward_bounded.reward_bounded_until_probs(
            dtmc.transitions, state_set(dtmc, path.left), state_set(dtmc, path.right),
            levels, _reward_bound(path.bound))
    objective = path.path
    if any(_has_operator(child) for child in _children(objective)):
        raise CheckError("P and R operators inside a conditional formula are not supported",
                         path.span)
    return conditional.conditional_values(
        dtmc, state_set(dtmc, path.condition),
        lambda chain: path_probs(chain.dtmc, objective).value,
        _condition_name(path.condition), path.span)


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


def _bounded_operator(dtmc: DTMC, op: ProbOp | RewardOp,
                      must_decide: IntArray | None = None) -> BoolArray:
    """``P~p [..]`` or ``R~r [..]`` as a mask: the value compared with the bound.

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


def _decide(dtmc: DTMC, op: ProbOp | RewardOp, threshold: float,
            must_decide: IntArray | None) -> tuple[Bounds, BoolArray, BoolArray]:
    """The operator's numbers, where the bound certainly holds, and where it is undecided."""
    numbers = path_probs(dtmc, op.path) if isinstance(op, ProbOp) else path_rewards(dtmc, op)
    holds, undecided = numbers.compare(op.op, threshold)
    if must_decide is not None:
        undecided = undecided & np.isin(np.arange(dtmc.num_states), must_decide)
    return numbers, holds, undecided


def _until(dtmc: DTMC, remain: BoolArray, target: BoolArray,
           bound: TimeBound | None) -> Bounds:
    """Dispatch ``remain U target`` to the kernel for its step bound."""
    P = dtmc.transitions
    if bound is None:
        return kernels.until_probs(P, remain, target)
    k = _steps(bound.value)
    match bound.op:
        case "<=":
            return kernels.bounded_until_probs(P, remain, target, k)
        case "<":
            # U<0 can never be met; U<k is U<=k-1.
            if k == 0:
                return Bounds.exact(np.zeros(dtmc.num_states))
            return kernels.bounded_until_probs(P, remain, target, k - 1)
        case ">=":
            return kernels.lower_bounded_until_probs(P, remain, target, k)
        case ">":
            return kernels.lower_bounded_until_probs(P, remain, target, k + 1)
    raise CheckError(f"step bound '{bound.op}' is not allowed on U, F or G", bound.span)


def _reward_structure(dtmc: DTMC, op: RewardOp | RewardBounded) -> RewardVectors:
    """The reward structure *op* names, or a CheckError that says where."""
    try:
        return dtmc.reward(op.reward)
    except (KeyError, IndexError):
        key = "" if op.reward is None else f" {op.reward!r}"
        raise CheckError(f"the model has no reward structure{key}", op.span) from None


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
    """Evaluate *expr* with the builder's expression compiler."""
    result = np.asarray(compile_expr(expr, dtmc.variable_names, dtmc.labels)(dtmc.states))
    result = np.broadcast_to(result, (dtmc.num_states,)).copy()
    return result if result.dtype == np.bool_ else result.astype(np.float64)


def _as_mask(result: Values, expr: Expr) -> BoolArray:
    """A leaf's values as a mask; boolean variables arrive as 0/1 integers."""
    if result.dtype == np.bool_:
        return np.asarray(result, dtype=np.bool_)
    if np.all((result == 0) | (result == 1)):
        return np.asarray(result == 1, dtype=np.bool_)
    raise CheckError("expected a boolean state formula", expr.span)


def _everywhere(dtmc: DTMC) -> BoolArray:
    return np.ones(dtmc.num_states, dtype=bool)


def _children(expr: Expr | PathFormula | RewardPath) -> Iterator[Expr]:
    """The direct sub-expressions of a node, path operands and bounds included."""
    match expr:
        case Unary(operand=a) | Next(operand=a) | Reach(target=a):
            yield a
        case Binary(left=a, right=b):
            yield from (a, b)
        case Ite(cond=a, then=b, otherwise=c):
            yield from (a, b, c)
        case Call(args=args):
            yield from args
        case Until(left=a, right=b):
            yield from (a, b)
        case Eventually(operand=a) | Globally(operand=a):
            yield a
        case ProbOp(path=path) | RewardOp(path=path):
            yield from _children(path)


def _has_operator(expr: Expr) -> bool:
    """Whether a ``P`` or ``R`` operator occurs anywhere in *expr*."""
    if isinstance(expr, ProbOp | RewardOp):
        return True
    return any(_has_operator(child) for child in _children(expr))


def _labels_in(expr: Expr) -> Iterator[LabelRef]:
    """Every label reference in *expr*."""
    if isinstance(expr, LabelRef):
        yield expr
    for child in _children(expr):
        yield from _labels_in(child)
