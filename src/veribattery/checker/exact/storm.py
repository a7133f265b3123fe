"""Storm's conditional and reward-bounded formulas in exact rational arithmetic (``--exact``).

The same constructions as the float checker (:mod:`~veribattery.checker.kernels.conditional`,
:mod:`~veribattery.checker.kernels.reward_bounded`), on the rational transition matrix:

* ``P(phi | F b) = P(phi ∧ F b) / P(F b)`` and ``E[R_a | F b] = E[R_a · 1{F b}] / P(F b)``,
  the numerators solved exactly SCC by SCC; states where ``F b`` is impossible hold
  NaN (undefined), and an initial one is :class:`ConditionUnreachable`;
* ``U{"r"}<=T``: the backward programme over reward levels, each level's
  zero-reward closure solved exactly; ``U{"r"}>=B``: unbounded until on the product
  with the reward still needed.

Objectives of a conditional with a step or reward bound are not supported here.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from gmpy2 import mpq

from veribattery._types import BoolArray, IntArray
from veribattery.checker import kernels
from veribattery.checker.exact.numeric import (
    ExactValues,
    exact_literal,
    indicator,
    prepared_system,
    reach_rewards,
    until_probs,
)
from veribattery.checker.exact.solve import row_products, solve
from veribattery.checker.formula.leaves import integer_limit
from veribattery.checker.kernels.conditional import ConditionUnreachable
from veribattery.checker.workspace import Workspace
from veribattery.errors import CheckError, Span, UndefinedResult
from veribattery.explore.dtmc import DTMC
from veribattery.explore.exact.dtmc import ExactDTMC, ExactRewards
from veribattery.explore.exact.rational import ObjectArray
from veribattery.lang.nodes import (
    Conditional,
    ConditionalReach,
    Eventually,
    Expr,
    Globally,
    LabelRef,
    Next,
    Release,
    RewardBounded,
    Until,
    WeakUntil,
)
from veribattery.lang.property_rules import STEPS_REWARD

#: The recursion passes its state-set evaluator
#: (:func:`veribattery.checker.exact.pctl.state_set`): state formulas nest inside these
#: path formulas, and the recursion over them lives there.
StateSet = Callable[[ExactDTMC, Workspace, Expr], BoolArray]

_ZERO = mpq(0)
_ONE = mpq(1)
_UNDEFINED = float("nan")


# ---------------------------------------------------------------------------
# Conditional formulas
# ---------------------------------------------------------------------------


def conditional_probs(model: ExactDTMC, workspace: Workspace, path: Conditional, *,
                      state_set: StateSet) -> ObjectArray:
    """``P=? [ phi || F b ]`` per state: exact rationals, NaN where ``F b`` is impossible.

    :raises ConditionUnreachable: when ``F b`` has probability 0 from an initial state.
    :raises UndefinedResult: for an objective with a step or reward bound.
    """
    x, possible = _condition(model, workspace, path.condition, path.span,
                              state_set=state_set)
    P, probabilities = model.dtmc.transitions, model.probabilities
    objective = path.path
    if isinstance(objective, Next):
        hits = indicator(state_set(model, workspace, objective.operand))
        everything = np.arange(model.dtmc.num_states)
        weighted = np.asarray(hits * x, dtype=object)
        numerator = row_products(P, probabilities, everything, weighted)
        on_b = row_products(P, probabilities, everything, hits)
        b = state_set(model, workspace, path.condition)
        return _divide(np.where(b, on_b, numerator), x, possible)
    reduced = _as_until(model, workspace, objective, state_set=state_set)
    if reduced is None:
        raise UndefinedResult("a conditional objective with a step or reward bound is not "
                              "supported in exact arithmetic", objective.span)
    remain, target, negated = reduced
    b = state_set(model, workspace, path.condition)
    ratio = _divide(_until_and_condition(model, workspace, remain, target, b, x), x, possible)
    if negated:
        ratio = np.asarray([_ONE - v if possible[i] else v for i, v in enumerate(ratio)],
                           dtype=object)
    return ratio


def conditional_reach_rewards(model: ExactDTMC, workspace: Workspace, rewards: ExactRewards,
                              path: ConditionalReach, *, state_set: StateSet) -> ExactValues:
    """``R=? [ F a || F b ]`` per state exactly (infinite and NaN as the float checker)."""
    x, possible = _condition(model, workspace, path.condition, path.span,
                              state_set=state_set)
    P = model.dtmc.transitions
    target = state_set(model, workspace, path.target)
    b = state_set(model, workspace, path.condition)
    b = b & ~target
    numerator = indicator(np.zeros_like(target))
    infinite = np.zeros_like(target)
    if b.any():  # the unconditional value once on b (none when b lies inside the target)
        plain = reach_rewards(model, workspace, rewards.total, target)
        infinite = ~kernels.prob0(P, ~target, b & plain.infinite, workspace=workspace)
        numerator = np.where(b & ~infinite, plain.values, _ZERO).astype(object)
    maybe = ~infinite & ~target & ~b & possible
    if maybe.any():
        rows = np.flatnonzero(maybe)
        offsets = np.asarray(rewards.total[rows] * x[rows], dtype=object)
        offsets = offsets + row_products(P, model.probabilities, rows, numerator)
        numerator[rows] = solve(prepared_system(model, workspace, maybe), offsets)
    return ExactValues(_divide(numerator, x, possible), infinite & possible)


def _condition(model: ExactDTMC, workspace: Workspace, condition: Expr, span: Span, *,
               state_set: StateSet) -> tuple[ObjectArray, BoolArray]:
    """``P(F b)`` exactly and where it is positive; an error if not from an initial state."""
    b = state_set(model, workspace, condition)
    everywhere = np.ones(b.size, dtype=bool)
    possible = ~kernels.prob0(model.dtmc.transitions, everywhere, b, workspace=workspace)
    if not possible[model.dtmc.initial].all():
        what = (f'F "{condition.name}"' if isinstance(condition, LabelRef)
                else f"after || (at {span})")
        raise ConditionUnreachable(f"the condition {what} has probability 0 from the initial "
                                   "state, so the conditional value is undefined", span)
    key = b"condition:" + np.packbits(b).tobytes()  # shared by the conditional properties
    kept = workspace.kernels.exact(model.dtmc.transitions)
    x = kept.get(key)
    if not isinstance(x, np.ndarray):
        x = until_probs(model, workspace, everywhere, b)
        kept[key] = x
    return x, possible


def _until_and_condition(model: ExactDTMC, workspace: Workspace, remain: BoolArray,
                         target: BoolArray, b: BoolArray, x: ObjectArray) -> ObjectArray:
    """``P(remain U target ∧ F b)``: known on *target* (x), *b* (the until) and ``!remain`` (0)."""
    P = model.dtmc.transitions
    until = until_probs(model, workspace, remain, target)
    fixed = target | b | ~remain
    known = np.where(target, x, np.where(b, until, _ZERO)).astype(object)
    positive = fixed & np.fromiter((v != 0 for v in known), dtype=bool, count=known.size)
    maybe = ~fixed & ~kernels.prob0(P, np.ones_like(b), positive, workspace=workspace)
    result = np.where(fixed, known, _ZERO).astype(object)
    if maybe.any():
        rows = np.flatnonzero(maybe)
        rhs = row_products(P, model.probabilities, rows, result)
        result[rows] = solve(prepared_system(model, workspace, maybe), rhs)
    return result


def _as_until(model: ExactDTMC, workspace: Workspace, path: object, *, state_set: StateSet
              ) -> tuple[BoolArray, BoolArray, bool] | None:
    """An unbounded path formula as ``remain U target`` or its negation (None otherwise)."""
    everywhere = np.ones(model.dtmc.num_states, dtype=bool)
    match path:
        case Until(left=left, right=right, bound=None):
            a, b = state_set(model, workspace, left), state_set(model, workspace, right)
            return a, b, False
        case Eventually(operand=operand, bound=None):
            return everywhere, state_set(model, workspace, operand), False
        case Globally(operand=operand, bound=None):
            return everywhere, ~state_set(model, workspace, operand), True
        case WeakUntil(left=left, right=right, bound=None):
            a, c = state_set(model, workspace, left), state_set(model, workspace, right)
            return a & ~c, ~a & ~c, True
        case Release(left=left, right=right, bound=None):
            a, c = state_set(model, workspace, left), state_set(model, workspace, right)
            return ~a, ~c, True
    return None


def _divide(numerator: ObjectArray, x: ObjectArray, possible: BoolArray) -> ObjectArray:
    """``numerator / x`` where the condition is possible, NaN elsewhere."""
    return np.asarray([n / d if ok else _UNDEFINED
                       for n, d, ok in zip(numerator, x, possible, strict=True)], dtype=object)


# ---------------------------------------------------------------------------
# Reward-bounded reachability
# ---------------------------------------------------------------------------


def reward_bounded_probs(model: ExactDTMC, workspace: Workspace, path: RewardBounded, *,
                         state_set: StateSet) -> ObjectArray:
    """``remain U{"r"}<=T target`` (or ``>=B``) per state exactly (Storm's semantics, see
    reward_bounded and reward_layers)."""
    rewards = _integer_rewards(model, path)
    limit = integer_limit(path.bound.op, exact_literal(path.bound.value))
    remain = state_set(model, workspace, path.left)
    target = state_set(model, workspace, path.right)
    if limit.gather:
        return _gathered(model, workspace, remain, target, rewards, max(limit.total, 0),
                         path.span)
    bound = limit.total
    n = model.dtmc.num_states
    if bound < 0:
        return indicator(np.zeros(n, dtype=bool))
    P, probabilities = model.dtmc.transitions, model.probabilities
    moving = remain & ~target & ~kernels.prob0(P, remain, target, workspace=workspace)
    positive = [int(v) for v in np.unique(rewards[moving & (rewards > 0)])]
    unit = math.gcd(*positive) if positive else 1
    groups = [(value // unit, np.flatnonzero(moving & (rewards == value))) for value in positive]
    zero_mask = moving & (rewards == 0)
    zero = np.flatnonzero(zero_mask)
    history: list[ObjectArray] = []
    keep = max((r for r, _ in groups), default=1)
    value = indicator(target)
    for k in range(bound // unit + 1):
        value = indicator(target)
        for r, states in groups:
            if k >= r:
                value[states] = row_products(P, probabilities, states, history[-r])
        if zero.size:
            value[zero] = solve(prepared_system(model, workspace, zero_mask),
                                row_products(P, probabilities, zero, value))
        history = [*history[-(keep - 1):], value] if keep > 1 else [value]
    return value


def _integer_rewards(model: ExactDTMC, path: RewardBounded) -> IntArray:
    """The exact rewards per step as non-negative integers, or an error naming a state."""
    if path.reward == STEPS_REWARD:
        return np.ones(model.dtmc.num_states, dtype=np.int64)
    structure = model_reward(model, path)
    total = structure.total
    for state, v in enumerate(total):
        if v < 0 or mpq(v).denominator != 1:
            name = f'"{structure.name}"' if structure.name else "(unnamed)"
            values = ", ".join(f"{var}={val}" for var, val in zip(
                model.dtmc.variable_names, model.dtmc.states[state], strict=True))
            raise CheckError(f"a reward bound needs non-negative integer rewards, but reward "
                             f"structure {name} gives {float(v):g} in state ({values})",
                             path.span)
    return np.array([int(v) for v in total], dtype=np.int64)


def model_reward(model: ExactDTMC, path: RewardBounded) -> ExactRewards:
    """The reward structure *path* names, or a CheckError that says where."""
    try:
        return model.reward(path.reward)
    except (KeyError, IndexError):
        raise CheckError(f"the model has no reward structure {path.reward!r}",
                         path.span) from None


def _gathered(model: ExactDTMC, workspace: Workspace, remain: BoolArray, target: BoolArray,
              rewards: IntArray, need: int, span: Span) -> ObjectArray:
    """``remain U{"r"}>=need target``: unbounded until on the gather product
    (:mod:`~veribattery.checker.kernels.reward_layers`), from layer *need*."""
    from veribattery.checker.kernels.reward_layers import (
        LayeredSets,
        layered_data,
        layered_rows,
        require_product_size,
    )

    dtmc = model.dtmc
    n = dtmc.num_states
    require_product_size(dtmc.transitions.nnz, need, need, span)
    layers = need + 1
    product = DTMC(layered_rows(dtmc.transitions, rewards, need, gather=True),
                   np.zeros((layers * n, 0), dtype=np.int64), (), need * n + dtmc.initial,
                   {}, ())
    laid = ExactDTMC(product, layered_data(model.probabilities, need, gather=True, one=_ONE),
                     (), model.constants)
    sets = LayeredSets.of(remain, target, need, gather=True)
    found = until_probs(laid, workspace, sets.remain, sets.target)
    return np.asarray(found[sets.answer], dtype=object)
