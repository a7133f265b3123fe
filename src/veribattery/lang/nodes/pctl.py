"""PCTL nodes: path formulas and the ``P``, ``R`` and ``S`` operators, quantifiers and filters.

They are expressions too, so that they nest inside boolean connectives in property
files: :data:`Expr` is the union of every expression node, these and those of :mod:`.expr`.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, TypeAlias

from veribattery.errors import NO_SPAN, Span
from veribattery.lang.nodes.expr import (
    Binary,
    BoolLit,
    Call,
    DoubleLit,
    Ident,
    IntLit,
    Ite,
    LabelRef,
    Unary,
)
from veribattery.lang.nodes.ltl import CosafeReach, LtlPath

__all__ = [
    "BOUND_RELATIONS",
    "Bound",
    "BoundOp",
    "Conditional",
    "ConditionalReach",
    "Cumulative",
    "Eventually",
    "Expr",
    "Filter",
    "FilterOp",
    "Globally",
    "Instantaneous",
    "LongRun",
    "Multi",
    "Next",
    "PathFormula",
    "ProbOp",
    "Quantified",
    "QueryOp",
    "Reach",
    "ReachNext",
    "ReachUntil",
    "Release",
    "RewardBounded",
    "RewardOp",
    "RewardPath",
    "SteadyOp",
    "TimeBound",
    "TimeInterval",
    "Total",
    "Until",
    "WeakUntil",
]

# ---------------------------------------------------------------------------
# Property operators (PCTL)
# ---------------------------------------------------------------------------

BoundOp: TypeAlias = Literal["<", "<=", ">", ">="]
#: What each bound operator means, for any ordered values: floats, arrays, rationals.
BOUND_RELATIONS: Mapping[str, Callable[[Any, Any], Any]] = {
    "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge,
}
#: ``"=?"`` asks for the value; the others compare it with a bound.
QueryOp: TypeAlias = Literal["=?", "<", "<=", ">", ">="]


@dataclass(frozen=True, slots=True)
class TimeBound:
    """A step bound on a temporal operator: ``<=k``, ``<k``, ``>=k``, ``>k`` (``=k`` for I)."""

    op: Literal["<", "<=", ">", ">=", "="]
    value: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class TimeInterval:
    """A step interval ``[low,high]`` on a temporal operator (both ends included)."""

    low: Expr
    high: Expr
    span: Span = field(default=NO_SPAN, compare=False)


Bound: TypeAlias = TimeBound | TimeInterval


@dataclass(frozen=True, slots=True)
class Next:
    """``X phi``."""

    operand: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Until:
    """``left U right``, optionally step-bounded."""

    left: Expr
    right: Expr
    bound: Bound | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class WeakUntil:
    """``left W right``: ``left U right`` or ``G left``, optionally step-bounded."""

    left: Expr
    right: Expr
    bound: Bound | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Release:
    """``left R right``: *right* holds up to and including the first *left* state."""

    left: Expr
    right: Expr
    bound: Bound | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Eventually:
    """``F phi``, optionally step-bounded (equivalent to ``true U phi``)."""

    operand: Expr
    bound: Bound | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Globally:
    """``G phi``, optionally step-bounded."""

    operand: Expr
    bound: Bound | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Cumulative:
    """Reward path ``C<=k``: reward accumulated over the first k steps."""

    bound: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Instantaneous:
    """Reward path ``I=k``: expected state reward at step k."""

    time: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Reach:
    """Reward path ``F phi``: reward accumulated until phi is first reached."""

    target: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Total:
    """Reward path ``C``: the total reward accumulated along the whole path."""

    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class LongRun:
    """Reward path ``S``: the long-run average reward per step."""

    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class ReachUntil:
    """Reward path ``left U right``: reward until *right*, infinite unless it is sure."""

    left: Expr
    right: Expr
    span: Span = field(default=NO_SPAN, compare=False)


# --- Storm's reward-bounded and conditional formulas (checker/reward_bounded.py,
# --- checker/conditional.py).


@dataclass(frozen=True, slots=True)
class RewardBounded:
    """``left U{"r"}<=T right`` (``F{"r"}<=T right`` has *left* ``true``), as in Storm.

    *right* is reached through *left* states with at most T (``>=B``: at least B; then
    *left* is ``true``) of reward structure *reward* accumulated, the step that enters
    *right* included. *reward* is a name or a 0-based index, as in :class:`RewardOp`.
    """

    left: Expr
    right: Expr
    reward: str | int
    bound: TimeBound
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class ReachNext:
    """Reward path ``X phi``: the first step's reward, infinite unless ``X phi`` is sure."""

    target: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Conditional:
    """``P=? [ path || F condition ]``: *path* given that *condition* is reached (Storm)."""

    path: PathFormula
    condition: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class ConditionalReach:
    """Reward path ``F target || F condition``: reward to *target*, given ``F condition``."""

    target: Expr
    condition: Expr
    span: Span = field(default=NO_SPAN, compare=False)


PathFormula: TypeAlias = (
    Next | Until | Eventually | Globally | WeakUntil | Release | RewardBounded | Conditional
    | LtlPath
)
RewardPath: TypeAlias = (
    Cumulative | Instantaneous | Reach | Total | LongRun | ReachUntil | ReachNext
    | ConditionalReach | CosafeReach
)


@dataclass(frozen=True, slots=True)
class ProbOp:
    """``P=? [path]`` or ``P~p [path]``."""

    op: QueryOp
    bound: Expr | None
    path: PathFormula
    span: Span = field(default=NO_SPAN, compare=False)
    #: ``Pmin``/``Rmin`` or ``Pmax``/``Rmax`` (None for plain ``P``/``R``): read on MDPs,
    #: ignored on DTMCs (as PRISM does).
    direction: Literal["min", "max"] | None = None


@dataclass(frozen=True, slots=True)
class RewardOp:
    """``R{"name"}=? [path]``, ``R=? [path]`` (first structure), or with a bound.

    *reward* is the structure's name, its 0-based index (``R{2}`` is index 1), or
    None for the first structure.
    """

    reward: str | int | None
    op: QueryOp
    bound: Expr | None
    path: RewardPath
    span: Span = field(default=NO_SPAN, compare=False)
    #: ``Pmin``/``Rmin`` or ``Pmax``/``Rmax`` (None for plain ``P``/``R``): read on MDPs,
    #: ignored on DTMCs (as PRISM does).
    direction: Literal["min", "max"] | None = None


@dataclass(frozen=True, slots=True)
class SteadyOp:
    """``S=? [phi]`` or ``S~p [phi]``: the long-run probability of being in *phi*."""

    op: QueryOp
    bound: Expr | None
    operand: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Quantified:
    """CTL: ``A [path]`` (on all paths) or ``E [path]`` (on some path)."""

    quantifier: Literal["A", "E"]
    path: PathFormula
    span: Span = field(default=NO_SPAN, compare=False)


FilterOp: TypeAlias = Literal[
    "min", "max", "argmin", "argmax", "count", "sum", "avg", "first", "range",
    "forall", "exists", "print", "printall", "state",
]


@dataclass(frozen=True, slots=True)
class Filter:
    """``filter(op, operand, states)``; *states* None means all states."""

    op: FilterOp
    operand: Expr
    states: Expr | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Multi:
    """``multi(q1, q2, ...)``: a multi-objective query on an MDP (PRISM's), every
    objective a ``P`` or ``R`` operator; all bounded (achievability: does one
    strategy meet them all?) or one ``=?`` (its optimum over the strategies that
    meet the others)."""

    objectives: tuple[Expr, ...]
    span: Span = field(default=NO_SPAN, compare=False)


Expr: TypeAlias = (
    IntLit
    | DoubleLit
    | BoolLit
    | Ident
    | LabelRef
    | Unary
    | Binary
    | Ite
    | Call
    | ProbOp
    | RewardOp
    | SteadyOp
    | Quantified
    | Filter
    | Multi
)
