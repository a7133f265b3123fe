"""The leaves of the PCTL recursion and the literals in its formulas.

Operator-free state expressions evaluated in every state (:func:`leaf_values`,
:func:`as_mask`), the boolean connectives over state sets, step bounds and other
numeric literals (:func:`step_bound`), and the reward structure an operator names.
Shared by the float recursion (:mod:`~veribattery.checker.formula.pctl`) and the exact
one (:mod:`~veribattery.checker.exact.pctl`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import NamedTuple, Protocol, TypeAlias

import numpy as np

from veribattery._types import BoolArray, FloatArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.errors import CheckError
from veribattery.explore.compile import arrays
from veribattery.explore.compile.expr import compile_expr
from veribattery.explore.dtmc import DTMC, RewardVectors
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    BoolLit,
    Call,
    Conditional,
    DoubleLit,
    Expr,
    Filter,
    Ident,
    IntLit,
    LabelRef,
    LtlPath,
    PathFormula,
    ProbOp,
    Quantified,
    Release,
    RewardBounded,
    RewardOp,
    SteadyOp,
    TimeBound,
    TimeInterval,
    Unary,
    Until,
    WeakUntil,
)
from veribattery.lang.ops import INT_MAX
from veribattery.lang.property_rules import STEPS_REWARD

_OPERATORS = (ProbOp, RewardOp, SteadyOp, Quantified, Filter)

Values: TypeAlias = FloatArray | BoolArray
#: What :func:`~veribattery.checker.formula.pctl.values` returns: certified numbers, or a state set.
Result: TypeAlias = Bounds | BoolArray

#: The boolean connectives over state sets, by operator.
CONNECTIVES: dict[str, Callable[[BoolArray, BoolArray], BoolArray]] = {
    op: arrays.BINARY[op] for op in ("&", "|", "=>", "<=>")  # over state sets
}

class Roundable(Protocol):
    """A number ``math.floor`` and ``math.ceil`` take: a float, or an exact rational."""

    def __floor__(self) -> int: ...

    def __ceil__(self) -> int: ...


class RewardLimit(NamedTuple):
    """A reward bound on integer rewards: the largest total that ``<=T`` / ``<T`` admits,
    or (*gather*) the smallest that ``>=B`` / ``>B`` requires."""

    total: int
    gather: bool


def reward_limit(bound: TimeBound) -> RewardLimit:
    """The integer limit of the reward bound *bound* (see :func:`integer_limit`)."""
    return integer_limit(bound.op, literal_number(bound.value))


def integer_limit(op: str, value: Roundable) -> RewardLimit:
    """The integer limit of a reward bound ``op value``: a fractional T or B is rounded
    inward, as the total is an integer (*value* may be a rational, read exactly)."""
    match op:
        case "<=":
            return RewardLimit(math.floor(value), gather=False)
        case "<":
            return RewardLimit(math.ceil(value) - 1, gather=False)
        case ">=":
            return RewardLimit(math.ceil(value), gather=True)
    return RewardLimit(math.floor(value) + 1, gather=True)


def _condition_name(condition: Expr) -> str:
    """The condition as an error message names it."""
    if isinstance(condition, LabelRef):
        return f'F "{condition.name}"'
    return f"after || (at {condition.span})"


def step_interval(bound: TimeBound | TimeInterval,
                  read: Callable[[Expr], int] | None = None) -> tuple[int, int | None]:
    """The steps ``[low, high]`` (``high`` None: unbounded) at which the target counts.

    :param read: reads each step bound (default :func:`step_bound`; the exact engines
        pass :func:`exact_step_bound`, which also holds them to their limit).
    """
    read = step_bound if read is None else read
    if isinstance(bound, TimeInterval):
        return read(bound.low), read(bound.high)
    k = read(bound.value)
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
    require_nonnegative_rewards(structure.name, (structure.state, structure.transition), op)
    return structure


def require_nonnegative_rewards(name: str | None, values: tuple[FloatArray, ...],
                                op: RewardOp | RewardBounded) -> None:
    """Refuse a reward structure with a negative reward, naming the operator that reads
    it (the build refuses infinite and NaN ones). Every reward operator here, and its
    certificate, assumes nonnegative rewards; Storm computes some such properties
    (``C<=k``, ``I=k``), with rewards that are not monotone in the step.

    :raises CheckError: at *op*.
    """
    if any(np.any(array < 0) for array in values):
        shown = "" if name is None else f' "{name}"'
        raise CheckError(f"the reward structure{shown} has negative rewards: veribattery "
                         "checks nonnegative rewards only", op.span)


def literal_number(expr: Expr) -> float:
    """The value of a literal (constants are substituted before checking)."""
    match expr:
        case IntLit(value=value) | DoubleLit(value=value):
            return float(value)
        case Unary(op="-", operand=operand):
            return -literal_number(operand)
    raise CheckError("expected a numeric constant", expr.span)


#: The most steps the exact engines iterate: their rationals grow with each step, and so
#: does its cost (``F<=k`` on a three-state chain whose values never settle: 10^4 steps
#: take 1 s, 10^5 a minute, 10^6 more than an hour).
EXACT_STEP_LIMIT = 100_000


def step_bound(expr: Expr) -> int:
    """A step bound: a non-negative integer literal, at most the engine's largest int
    (:data:`~veribattery.lang.ops.INT_MAX`; above it a bound would wrap or overflow)."""
    if isinstance(expr, IntLit):  # exactly: a float would round bounds above 2^53
        value: float | int = expr.value
    else:
        value = literal_number(expr)
    if value < 0 or value != int(value):
        raise CheckError(f"step bound must be a non-negative integer, not {value:g}",
                         expr.span)
    if value > INT_MAX:
        raise CheckError(f"step bound {value} is too large (at most 2^63 - 1)", expr.span)
    return int(value)


def exact_step_bound(expr: Expr) -> int:
    """A step bound for the exact engines: :func:`step_bound`, at most
    :data:`EXACT_STEP_LIMIT`."""
    steps = step_bound(expr)
    if steps > EXACT_STEP_LIMIT:
        raise CheckError(f"step bound {steps} is too large for exact arithmetic (at most "
                         f"{EXACT_STEP_LIMIT:,} steps)", expr.span)
    return steps


def _operands(path: PathFormula) -> tuple[Expr, ...]:
    if isinstance(path, Until | WeakUntil | Release | RewardBounded):
        return (path.left, path.right)
    if isinstance(path, Conditional):
        return (path.condition,)
    if isinstance(path, LtlPath):
        from veribattery.checker.ltl.propositions import propositions

        return propositions(path.formula).operands
    return (path.operand,)


# ---------------------------------------------------------------------------
# Leaves: labels and operator-free state expressions
# ---------------------------------------------------------------------------


def leaf_values(dtmc: DTMC, expr: Expr) -> Values:
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


def as_mask(result: Values, expr: Expr) -> BoolArray:
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


def has_operator(expr: Expr) -> bool:
    """Whether *expr* needs the checker: an operator, a filter or ``round`` occurs in it."""
    return any(isinstance(node, _OPERATORS) or (isinstance(node, Call) and node.func == "round")
               for node in walk(expr))


def _labels_in(expr: Expr) -> Iterator[LabelRef]:
    """Every label reference in *expr*."""
    return (node for node in walk(expr) if isinstance(node, LabelRef))
