"""Parse tree → AST for the property language: temporal operators, P/R/S, CTL, filters.

Constructs that parse but cannot be checked (LTL: a temporal operator nested in
another one) become an :class:`Unsupported` marker that propagates up to the
enclosing property, which is then kept with its reason, so that a properties
file always parses as a whole and ``--property`` can pick the others.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Literal, Protocol, TypeAlias, cast

from veribattery.errors import PrismSemanticError, PrismSyntaxError, Span
from veribattery.lang.nodes import (
    BoolLit,
    Conditional,
    ConditionalReach,
    CosafeReach,
    Cumulative,
    Eventually,
    Expr,
    Filter,
    FilterOp,
    Globally,
    Instantaneous,
    LongRun,
    LtlNode,
    LtlPath,
    Multi,
    Next,
    PathFormula,
    ProbOp,
    Quantified,
    QueryOp,
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
    Until,
    WeakUntil,
)
from veribattery.lang.ops import OperatorError, int_literal
from veribattery.lang.path_values import (
    Temporal,
    Unsupported,
    Value,
    first_bad,
    is_ltl,
    is_path,
    ltl_temporal,
)

_TimeOp: TypeAlias = Literal["<", "<=", ">", ">=", "="]
_FILTER_OPS = frozenset({
    "min", "max", "argmin", "argmax", "count", "sum", "avg", "first", "range",
    "forall", "exists", "print", "printall", "state",
})
_FILTER_ALIASES = {"+": "sum", "&": "forall", "|": "exists"}
#: The Storm operator ``T=? [F phi]`` is ``R=? [F phi]`` for this reward structure name.
STEPS_REWARD = "\0steps"
#: Storm's expected-steps operators and the objective each names on an MDP.
_STEPS_DIRECTIONS: dict[str, str | None] = {"T": None, "Tmin": "min", "Tmax": "max"}


@dataclass(frozen=True, slots=True)
class _Legacy:
    """An old-style filter suffix ``{states}{min}{max}`` inside P, R or S."""

    states: Expr
    ops: tuple[str, ...]
    span: Span


@dataclass(frozen=True, slots=True)
class _RefusedLegacy:
    """A filter suffix whose states are not a state formula (``{F a}``): the refusal."""

    refusal: Unsupported


#: ``Pmin``, ``Rmax``, ``R{"r"}min``, ``R{2}max``: where a P or R operator names its direction.
_DIRECTION = re.compile(r'[PR](min|max)?\s*(?:\{\s*(?:"[^"]*"|\d+)\s*\}\s*(min|max)?)?')


class Meta(Protocol):
    """Where a rule's text starts and ends (lark's ``Meta`` or the fast parser's)."""

    line: int
    column: int
    start_pos: int
    end_pos: int


def _path_formula(path: Value) -> PathFormula | Unsupported:
    """The path formula of a P, A or E operator; a state formula ``phi`` is ``false U phi``."""
    if isinstance(path, Unsupported):
        return path
    if is_ltl(path):
        return LtlPath(cast(LtlNode, path), path.span)
    if not isinstance(path, Temporal):
        return Until(BoolLit(False, path.span), cast(Expr, path), None, path.span)
    if path.op == "X":
        if path.bound is not None:
            return Unsupported("X (next) takes no time bound", path.span)
        return Next(path.right, path.span)
    if path.op == "RB":
        return RewardBounded(cast(Expr, path.left), path.right, cast(str | int, path.reward),
                             cast(TimeBound, path.bound), path.span)
    if path.op == "F":
        return Eventually(path.right, path.bound, path.span)
    if path.op == "G":
        return Globally(path.right, path.bound, path.span)
    kinds: dict[str, type[Until | WeakUntil | Release]] = {
        "U": Until, "W": WeakUntil, "R": Release,
    }
    return kinds[path.op](cast(Expr, path.left), path.right, path.bound, path.span)


def _legacy_filter(legacy: _Legacy, operand: Expr, span: Span) -> Filter:
    """``{states}`` is the value in that one state, ``{min}``/``{max}`` the extreme over
    them and both the range, as PRISM converts its old-style filters."""
    ops = set(legacy.ops)
    op: FilterOp = "range" if len(ops) == 2 else cast(FilterOp, ops.pop()) if ops else "state"
    return Filter(op, operand, legacy.states, span)


def _split_legacy(children: list[Any]) -> tuple[list[Any], _Legacy | Unsupported | None]:
    """The operator's own children, and its filter suffix (or the suffix's refusal)."""
    if children and isinstance(children[-1], _Legacy):
        return children[:-1], children[-1]
    if children and isinstance(children[-1], _RefusedLegacy):
        return children[:-1], children[-1].refusal
    return children, None


class PropertyRules:
    """One method per rule of the property grammar, ``rule(meta, children) -> value``.

    Plain Python (no lark): the lark transformer and the fast parser
    (:mod:`veribattery.lang.fastparse`) both call these, so both build the same nodes.
    """

    _source: str
    _text: str

    def _span(self, meta: Meta) -> Span:
        return Span(meta.line, meta.column, self._source)

    def _direction(self, meta: Meta) -> Literal["min", "max"] | None:
        """``min``/``max`` of ``Pmin``/``Rmax``: the operator word at the rule's start."""
        found = _DIRECTION.match(self._text, meta.start_pos)
        word = (found.group(1) or found.group(2)) if found is not None else None
        return "min" if word == "min" else "max" if word == "max" else None

    def _wrap(self, node: Expr, legacy: _Legacy | Unsupported | None,
              meta: Meta) -> Expr | Unsupported:
        if legacy is None:
            return node
        if isinstance(legacy, Unsupported):
            return legacy
        return _legacy_filter(legacy, node, self._span(meta))

    def time_bound(self, meta: Meta, children: list[Any]) -> TimeBound | Unsupported:
        op, value = children
        bad = first_bad([value])
        return bad or TimeBound(cast(_TimeOp, str(op)), value, self._span(meta))

    def time_interval(self, meta: Meta, children: list[Any]) -> TimeInterval | Unsupported:
        bad = first_bad(children)
        return bad or TimeInterval(children[0], children[1], self._span(meta))

    def temporal_unop(self, meta: Meta, children: list[Any]) -> Value:
        op, *rest = children
        bound = rest[0] if len(rest) == 2 else None
        if is_path(rest[-1]):
            return ltl_temporal(str(op), bound, None, rest[-1], self._span(meta))
        bad = first_bad(rest)
        if bad is not None:
            return bad
        return Temporal(str(op), bound, None, rest[-1], self._span(meta))

    def temporal_binop(self, meta: Meta, children: list[Any]) -> Value:
        left, op, *rest = children
        bound = rest[0] if len(rest) == 2 else None
        if is_path(left) or is_path(rest[-1]):
            return ltl_temporal(str(op), bound, left, rest[-1], self._span(meta))
        bad = first_bad([left, *rest])
        if bad is not None:
            return bad
        return Temporal(str(op), bound, left, rest[-1], self._span(meta))

    def query_value(self, meta: Meta, children: list[Any]) -> tuple[QueryOp, Expr | None]:
        return "=?", None

    def query_bound(self, meta: Meta, children: list[Any]) -> Any:
        op, bound = children
        bad = first_bad([bound])
        return bad or (str(op), bound)

    def legacy_op(self, meta: Meta, children: list[str]) -> str:
        return str(children[1])

    def state_filter(self, meta: Meta, children: list[Any]) -> _Legacy | _RefusedLegacy:
        states, *ops = children
        bad = first_bad([states])
        # (kept apart from an Unsupported operand: the operator would read it as its own)
        return _RefusedLegacy(bad) if bad else _Legacy(states, tuple(ops), self._span(meta))

    def prob_op(self, meta: Meta, children: list[Any]) -> Value:
        children, legacy = _split_legacy(children)
        query, path = children
        for item in (query, path, legacy):
            if isinstance(item, Unsupported):
                return item
        formula = _path_formula(path)
        if isinstance(formula, Unsupported):
            return formula
        node = ProbOp(query[0], query[1], formula, self._span(meta), self._direction(meta))
        return self._wrap(node, legacy, meta)

    def multi_objective(self, meta: Meta, children: list[Any]) -> Multi | Unsupported:
        return first_bad(children) or Multi(tuple(children), self._span(meta))

    def reward_by_name(self, meta: Meta, children: list[str]) -> str:
        return str(children[0])[1:-1]

    def reward_by_index(self, meta: Meta, children: list[str]) -> int:
        # R{2} is the second structure; nodes store 0-based indices.
        try:
            return int_literal(children[0]) - 1
        except OperatorError as exc:
            raise PrismSyntaxError(exc.message, self._span(meta)) from None

    def cumulative(self, meta: Meta, children: list[Any]) -> RewardPath | Unsupported:
        bound = children[0] if children else None
        if bound is None:
            return Total(self._span(meta))
        if isinstance(bound, Unsupported):
            return bound
        if isinstance(bound, TimeBound) and bound.op == "<=":
            return Cumulative(bound.value, self._span(meta))
        return Unsupported("cumulative rewards take C or C<=k", self._span(meta))

    def instantaneous(self, meta: Meta, children: list[Any]) -> RewardPath | Unsupported:
        bound = children[0]
        if isinstance(bound, Unsupported):
            return bound
        if not isinstance(bound, TimeBound) or bound.op != "=":
            return Unsupported("instantaneous rewards need I=k", self._span(meta))
        return Instantaneous(bound.value, self._span(meta))

    def steady_reward(self, meta: Meta, children: list[Any]) -> RewardPath:
        return LongRun(self._span(meta))

    def reach(self, meta: Meta, children: list[Any]) -> RewardPath | Unsupported:
        path = children[0]
        if isinstance(path, Unsupported):
            return path
        if is_ltl(path):
            return CosafeReach(cast(LtlNode, path), self._span(meta))
        if not isinstance(path, Temporal):
            # A state formula is a co-safe property decided at once: false U phi.
            return ReachUntil(BoolLit(False, path.span), path, self._span(meta))
        if path.bound is None and path.op == "X":
            return ReachNext(path.right, self._span(meta))
        if path.bound is None and path.op in ("F", "U"):
            if path.op == "F":
                return Reach(path.right, self._span(meta))
            return ReachUntil(cast(Expr, path.left), path.right, self._span(meta))
        if path.bound is None and path.op in ("G", "W", "R"):
            # LTL, refused by the checker unless co-safe (it is not): one rule, one message
            return CosafeReach(cast(LtlNode, ltl_temporal(path.op, None, path.left,
                                                          path.right, path.span)),
                               self._span(meta))
        return Unsupported("reward paths must be co-safe LTL (F, X, U over state formulas "
                           "and each other, unbounded), C, C<=k, I=k or S", self._span(meta))

    def reward_op(self, meta: Meta, children: list[Any]) -> Value:
        children, legacy = _split_legacy(children)
        reward = children[0] if isinstance(children[0], str | int) else None
        query, path = children[-2], children[-1]
        for item in (query, path, legacy):
            if isinstance(item, Unsupported):
                return item
        node = RewardOp(reward, query[0], query[1], path, self._span(meta),
                        self._direction(meta))
        return self._wrap(node, legacy, meta)

    def steps_op(self, meta: Meta, children: list[Any]) -> Value:
        name, _query, *rest = children
        direction = _STEPS_DIRECTIONS.get(str(name), "unknown")
        if direction == "unknown":
            raise PrismSyntaxError(f"unknown operator '{name}' (expected P, R, S, T, Tmin "
                                   "or Tmax)", self._span(meta))
        rest, legacy = _split_legacy(rest)
        for item in (rest[0], legacy):
            if isinstance(item, Unsupported):
                return item
        if not isinstance(rest[0], Reach):
            return Unsupported("T=? takes F phi", self._span(meta))
        node = RewardOp(STEPS_REWARD, "=?", None, rest[0], self._span(meta),
                        direction=cast(Literal["min", "max"] | None, direction))
        return self._wrap(node, legacy, meta)

    def steady_op(self, meta: Meta, children: list[Any]) -> Value:
        children, legacy = _split_legacy(children)
        query, operand = children
        bad = first_bad([operand, legacy]) or (query if isinstance(query, Unsupported) else None)
        if bad is not None:
            return bad
        return self._wrap(SteadyOp(query[0], query[1], operand, self._span(meta)), legacy, meta)

    def quantified(self, meta: Meta, children: list[Any]) -> Value:
        name, path = str(children[0]), children[1]
        if name not in ("A", "E"):
            raise PrismSyntaxError(f"unknown operator '{name}' (expected A or E)",
                                   self._span(meta))
        formula = _path_formula(path)
        if isinstance(formula, Unsupported):
            return formula
        return Quantified(cast(Literal["A", "E"], name), formula, self._span(meta))

    def filter_op(self, meta: Meta, children: list[str]) -> str:
        return str(children[0])

    def filter(self, meta: Meta, children: list[Any]) -> Value:
        name, operand, *states = children
        op = _FILTER_ALIASES.get(name, name)
        if op not in _FILTER_OPS:
            raise PrismSemanticError(
                f"unknown filter operator '{name}' (expected one of "
                f"{', '.join(sorted(_FILTER_OPS))})", self._span(meta))
        bad = first_bad([operand, *states])
        if bad is not None:
            return bad
        return Filter(cast(FilterOp, op), operand, states[0] if states else None,
                      self._span(meta))

    # ------------------------- Storm's reward-bounded and conditional formulas

    def reward_bounded_unop(self, meta: Meta, children: list[Any]) -> Value:
        _op, reward, bound, right = children
        return _reward_bounded(BoolLit(True, self._span(meta)), right, reward, bound,
                               self._span(meta))

    def reward_bounded_binop(self, meta: Meta, children: list[Any]) -> Value:
        left, _op, reward, bound, right = children
        return _reward_bounded(left, right, reward, bound, self._span(meta))

    def storm_bounded_unop(self, meta: Meta, children: list[Any]) -> Value:
        """``F^{rew{"r"}<=T} phi`` or ``F^{steps<=k} phi`` (Storm's bound lists)."""
        op, _power, *bounds, right = children
        return _storm_bounded(str(op), BoolLit(True, self._span(meta)), bounds, right,
                              self._span(meta))

    def storm_bounded_binop(self, meta: Meta, children: list[Any]) -> Value:
        left, op, _power, *bounds, right = children
        return _storm_bounded(str(op), left, bounds, right, self._span(meta))

    def named_reward_bound(self, meta: Meta, children: list[Any]) -> _StormBound:
        name, reward, bound = children
        return _StormBound(_bound_reference(str(name), ("rew",), self._span(meta)), reward,
                           bound)

    def reward_bound(self, meta: Meta, children: list[Any]) -> _StormBound:
        reward, bound = children
        return _StormBound("rew", reward, bound)

    def named_step_bound(self, meta: Meta, children: list[Any]) -> _StormBound:
        name, bound = children
        return _StormBound(_bound_reference(str(name), ("steps", "time"), self._span(meta)),
                           None, bound)

    def step_bound(self, meta: Meta, children: list[Any]) -> _StormBound:
        return _StormBound("steps", None, children[0])

    def conditional_prob_op(self, meta: Meta, children: list[Any]) -> Value:
        children, legacy = _split_legacy(children)
        query, path, _cond, condition = children
        for item in (query, path, legacy):
            if isinstance(item, Unsupported):
                return item
        if is_ltl(path):
            return Unsupported("a conditional formula (||) takes one temporal operator over "
                               "state formulas before ||, not LTL", self._span(meta))
        if not isinstance(path, Temporal):
            return Unsupported("P operator needs a path formula before ||", self._span(meta))
        objective = _path_formula(path)
        target = _condition_target(condition)
        if isinstance(objective, Unsupported):
            return objective
        if isinstance(target, Unsupported):
            return target
        node = ProbOp(query[0], query[1], Conditional(objective, target, self._span(meta)),
                      self._span(meta), self._direction(meta))
        return self._wrap(node, legacy, meta)

    def conditional_reach(self, meta: Meta, children: list[Any]) -> RewardPath | Unsupported:
        path, _cond, condition = children
        reach = self.reach(meta, [path])
        target = _condition_target(condition)
        if isinstance(reach, Unsupported):
            return reach
        if not isinstance(reach, Reach):
            return Unsupported("a conditional reward path must be F phi || F psi",
                               self._span(meta))
        if isinstance(target, Unsupported):
            return target
        return ConditionalReach(reach.target, target, self._span(meta))


def _reward_bounded(left: Any, right: Any, reward: Any, bound: Any, span: Span) -> Value:
    """``U{"r"}<=T`` / ``F{"r"}>=B``: one bound (``<=``, ``<``, ``>=``, ``>``), not an
    interval."""
    bad = first_bad([left, right, bound])
    if bad is not None:
        return bad
    if not isinstance(bound, TimeBound) or bound.op == "=":
        return Unsupported("a reward bound must be one of <=T, <T, >=B, >B", span)
    if bound.op in (">=", ">") and left != BoolLit(True):
        # (Storm's own limit: what the left operand must do on the way is not settled)
        return Unsupported("a lower reward bound (>=B, >B) is supported on F only, as in "
                           "Storm: write F{\"r\"}>=B phi", span)
    return Temporal("RB", bound, left, right, span, reward)


@dataclass(frozen=True, slots=True)
class _StormBound:
    """One bound of Storm's ``^{...}`` list: on accumulated reward *reward* (``rew``),
    or on steps (``steps``; ``time`` is the same in discrete time)."""

    reference: str
    reward: Any
    bound: Any


def _bound_reference(name: str, allowed: tuple[str, ...], span: Span) -> str:
    if name not in allowed:
        raise PrismSyntaxError(f"unknown bound reference '{name}' (expected rew{{\"name\"}}, "
                               "steps or time)", span)
    return "rew" if name == "rew" else "steps"


def _storm_bounded(op: str, left: Any, bounds: list[_StormBound], right: Any,
                   span: Span) -> Value:
    """``F^{...} phi`` / ``a U^{...} b`` with one bound: a reward bound as ``F{"r"}<=T``,
    a step bound as ``F<=k``; several at once (Storm's multi-dimensional bounds) are
    outside the language."""
    if len(bounds) != 1:
        return Unsupported("several bounds in one ^{...} (Storm's multi-dimensional "
                           "bounds) are not supported: give one", span)
    (bound,) = bounds
    if bound.reference == "rew":
        return _reward_bounded(left, right, bound.reward, bound.bound, span)
    bad = first_bad([left, right, bound.bound])
    if bad is not None:
        return bad
    return Temporal(op, bound.bound, None if op == "F" else left, right, span)


def _condition_target(condition: Any) -> Expr | Unsupported:
    """The *psi* of a condition ``F psi`` (the only condition Storm accepts)."""
    if isinstance(condition, Unsupported):
        return condition
    if isinstance(condition, Temporal) and condition.op == "F" and condition.bound is None:
        return condition.right
    span = condition.span if isinstance(condition, Temporal) else cast(
        Span, getattr(condition, "span", Span(1, 1)))
    return Unsupported("the condition after || must be F phi (unbounded)", span)
