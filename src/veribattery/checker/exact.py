"""PCTL model checking in exact rational arithmetic (``--exact``).

The same recursion as :mod:`~veribattery.checker.pctl` over an
:class:`~veribattery.explore.exact.dtmc.ExactDTMC`: state formulas are masks, ``P``
and ``R`` operators are per-state rationals (:class:`ExactValues`), and
``P~p``/``R~r`` compare them with the bound exactly. The qualitative pre-pass
is the float checker's (prob0/prob1 are graph searches, identical on the exact
matrix, which has the same structure); the maybe states are then solved SCC by
SCC in rationals (:mod:`~veribattery.checker.exact_solve`), and step-bounded
operators iterate exact matrix-vector products. Infinite expected rewards are
kept in a separate mask.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Mapping
from contextvars import ContextVar
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
from gmpy2 import mpq

from veribattery._types import BoolArray, FloatArray
from veribattery.checker import kernels
from veribattery.checker.bounds import Bounds
from veribattery.checker.exact_solve import Prepared, prepare, restrict, row_products, solve
from veribattery.checker.pctl import (
    _CONNECTIVES,
    _as_mask,
    _chain,
    _has_operator,
    _leaf,
    _steps,
)
from veribattery.checker.result import CheckResult
from veribattery.checker.workspace import Workspace
from veribattery.errors import CheckError, Span, UndefinedResult, VeribatteryError
from veribattery.explore.exact.dtmc import ExactDTMC, ExactRewards
from veribattery.explore.exact.rational import ExactScalar, ObjectArray, evaluate_rational, rational
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    BOUND_RELATIONS,
    Binary,
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
    Next,
    PathFormula,
    ProbOp,
    Property,
    Reach,
    RewardBounded,
    RewardOp,
    TimeBound,
    TimeInterval,
    Unary,
    Until,
)

__all__ = ["ExactCheckResult", "ExactValues", "check_exact", "exact_bounds", "exact_values"]

_ZERO = mpq(0)
_ONE = mpq(1)

#: The exact bounds of the property being checked (set by :func:`exact_values`).
_BOUNDS: ContextVar[Mapping[Span, mpq] | None] = ContextVar("exact_bounds", default=None)


@dataclass(frozen=True, slots=True)
class ExactValues:
    """Per-state rationals; *infinite* marks expected rewards that are infinite."""

    values: ObjectArray
    infinite: BoolArray

    @classmethod
    def finite(cls, values: ObjectArray) -> ExactValues:
        """Values none of which is infinite."""
        return cls(np.asarray(values, dtype=object), np.zeros(values.size, dtype=bool))

    def floats(self) -> FloatArray:
        """The nearest doubles (``inf`` where infinite)."""
        result = np.asarray(_TO_FLOAT(self.values), dtype=np.float64).reshape(-1)
        result[self.infinite] = np.inf
        return result


#: Elementwise ``float``/``mpq``/power-of-two-denominator over object arrays (C loops).
_TO_FLOAT = np.frompyfunc(float, 1, 1)
_TO_MPQ = np.frompyfunc(mpq, 1, 1)
_DYADIC = np.frompyfunc(lambda q: q.denominator.bit_count() == 1, 1, 1)


@dataclass(frozen=True, slots=True)
class ExactCheckResult(CheckResult):
    """A :class:`CheckResult` that also carries the exact answer.

    :param exact: the value at the first initial state as a :class:`fractions.Fraction`
        (None for booleans and infinite values).
    :param exact_values: per-state exact values (None for boolean results).
    """

    exact: Fraction | None = None
    exact_values: ExactValues | None = None


def check_exact(
    model: ExactDTMC, prop: Property | Expr, bounds: Mapping[Span, mpq] | None = None, *,
    workspace: Workspace | None = None,
) -> ExactCheckResult:
    """Check *prop* on *model* in exact arithmetic and report it at the initial states.

    :param bounds: exact values of ``P~p``/``R~r`` bounds by their span (see
        :func:`exact_bounds`); a bound not in it is read from its literal's digits.
    :param workspace: the caches to use and fill (graph searches, prepared systems),
        shared with the other checks given it; None: a new one for this check alone.
    :raises CheckError: when the property cannot be checked on this model.
    """
    prop = prop if isinstance(prop, Property) else Property(prop)
    start = time.perf_counter()
    result = exact_values(model, prop.formula, bounds or {}, workspace=workspace)
    initial = model.dtmc.initial
    if isinstance(result, ExactValues):
        plain = CheckResult.at_initial(prop, _enclosure(result), initial, 0.0)
        first = int(initial[0])
        exact = None if result.infinite[first] else _fraction(result.values[first])
        return ExactCheckResult(
            prop, plain.values, plain.value, time.perf_counter() - start, plain.lower,
            plain.upper, plain.precise, plain.bounds, exact=exact, exact_values=result)
    plain = CheckResult.at_initial(prop, result, initial, 0.0)
    return ExactCheckResult(prop, plain.values, plain.value, time.perf_counter() - start)


def _enclosure(values: ExactValues) -> Bounds:
    """Certified float bounds of exact values.

    A rational's conversion to float64 is within one unit in the last place of it
    (correctly rounded or truncated), so the neighbouring floats enclose it; values
    that a float represents exactly (0, 1, halves, infinities) are their own bounds.
    """
    floats = values.floats()
    # Only a rational with a power-of-two denominator can be a double: test those exactly.
    # A NaN float is an undefined (conditional) value: it stands for itself.
    undefined = np.isnan(floats)
    defined = np.flatnonzero(~values.infinite & ~undefined)
    candidates = defined[_DYADIC(values.values[defined]).astype(bool)]
    represented = values.infinite | undefined
    represented[candidates] = _TO_MPQ(floats[candidates]) == values.values[candidates]
    lower = np.where(represented, floats, np.nextafter(floats, -np.inf))
    upper = np.where(represented, floats, np.nextafter(floats, np.inf))
    return Bounds(floats, lower, upper)


def _fraction(value: mpq) -> Fraction:
    return Fraction(int(value.numerator), int(value.denominator))


def exact_bounds(formula: Expr, constants: Mapping[str, ExactScalar]) -> dict[Span, mpq]:
    """The exact value of every ``P~p``/``R~r`` bound in *formula* (before resolution), by span.

    Resolving a property folds ``P<=1/3`` into the double nearest 1/3; evaluated
    here from the expression as written, the bound stays 1/3.
    """
    found: dict[Span, mpq] = {}
    for node in walk(formula):
        if isinstance(node, ProbOp | RewardOp) and node.bound is not None:
            try:
                value = evaluate_rational(node.bound, constants, {}, 1)[0]
            except VeribatteryError:
                continue  # not a closed numeric expression: resolution reports it
            if not isinstance(value, bool | np.bool_):
                found[node.bound.span] = value
    return found


def exact_values(
    model: ExactDTMC, formula: Expr, bounds: Mapping[Span, mpq] | None = None, *,
    workspace: Workspace | None = None,
) -> ExactValues | BoolArray:
    """Per-state value of *formula*: rationals for ``P=?``/``R=?``, booleans otherwise.

    :param bounds: exact bound values by span (see :func:`exact_bounds`).
    :param workspace: as for :func:`check_exact`.
    """
    workspace = Workspace() if workspace is None else workspace
    if isinstance(formula, ProbOp) and formula.op == "=?":
        return ExactValues.finite(path_probs(model, workspace, formula.path))
    if isinstance(formula, RewardOp) and formula.op == "=?":
        return path_rewards(model, workspace, formula)
    if _has_operator(formula):
        token = _BOUNDS.set(bounds or {})
        try:
            return state_set(model, workspace, formula)
        finally:
            _BOUNDS.reset(token)
    leaf = _leaf(model.dtmc, formula)
    if leaf.dtype == np.bool_:
        return np.asarray(leaf, dtype=np.bool_)
    raise CheckError("--exact checks P and R operators and boolean formulas; "
                     "this is a numeric state expression", formula.span)


# ---------------------------------------------------------------------------
# State formulas
# ---------------------------------------------------------------------------

def state_set(model: ExactDTMC, workspace: Workspace, expr: Expr) -> BoolArray:
    """The states satisfying *expr*, bounded operators decided exactly."""
    if not _has_operator(expr):  # plain state predicate: evaluated whole, no recursion
        return _as_mask(_leaf(model.dtmc, expr), expr)
    match expr:
        case ProbOp() | RewardOp():
            return _bounded_operator(model, workspace, expr)
        case Unary(op="!", operand=operand):
            return ~state_set(model, workspace, operand)
        case Binary(op="&" | "|" as op):  # a chain of thousands: a loop, not a recursion
            masks = (state_set(model, workspace, operand) for operand in _chain(expr, op))
            return functools.reduce(_CONNECTIVES[op], masks)
        case Binary(op=op, left=left, right=right) if op in _CONNECTIVES:
            return _CONNECTIVES[op](state_set(model, workspace, left),
                                    state_set(model, workspace, right))
        case Ite(cond=cond, then=then, otherwise=otherwise) if _has_operator(expr):
            return np.where(state_set(model, workspace, cond), state_set(model, workspace, then),
                            state_set(model, workspace, otherwise))
    if _has_operator(expr):
        raise CheckError("P and R operators may only be combined with ! & | => <=> "
                         "and ?:", expr.span)
    return _as_mask(_leaf(model.dtmc, expr), expr)


def _bounded_operator(model: ExactDTMC, workspace: Workspace,
                      op: ProbOp | RewardOp) -> BoolArray:
    if op.op == "=?" or op.bound is None:
        raise CheckError("a query (=?) cannot be used as a state formula", op.span)
    if isinstance(op, ProbOp):
        numbers = ExactValues.finite(path_probs(model, workspace, op.path))
    else:
        numbers = path_rewards(model, workspace, op)
    exact = (_BOUNDS.get() or {}).get(op.bound.span)
    bound = _bound(op.bound) if exact is None else exact
    holds = np.asarray(BOUND_RELATIONS[op.op](numbers.values, bound), dtype=bool)
    return np.where(numbers.infinite, op.op in (">", ">="), holds)


def _bound(expr: Expr) -> mpq:
    """A probability or reward bound, read exactly from its digits."""
    match expr:
        case IntLit(value=value):
            return mpq(value)
        case DoubleLit(value=value, text=text):
            return rational(text) if text else rational(value)
        case Unary(op="-", operand=operand):
            return -_bound(operand)
    raise CheckError("expected a numeric constant", expr.span)


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
        case RewardBounded() | Conditional():
            return _storm_formula(model, workspace, path)
    raise UndefinedResult(
        f"{type(path).__name__} formulas are not supported in exact arithmetic", path.span)


def _storm_formula(model: ExactDTMC, workspace: Workspace,
                   path: RewardBounded | Conditional) -> ObjectArray:
    """Storm's reward-bounded and conditional formulas (checker/exact_storm_formulas.py)."""
    from veribattery.checker import exact_storm_formulas as storm

    if isinstance(path, RewardBounded):
        return storm.reward_bounded_probs(model, workspace, path)
    return storm.conditional_probs(model, workspace, path)


def _until(model: ExactDTMC, workspace: Workspace, remain: BoolArray, target: BoolArray,
           bound: TimeBound | TimeInterval | None) -> ObjectArray:
    if bound is None:
        return until_probs(model, workspace, remain, target)
    if isinstance(bound, TimeInterval):  # U[a,b]: remain for a steps, then U<=b-a
        low, high = _steps(bound.low), _steps(bound.high)
        if high < low:
            return _indicator(np.zeros_like(target))
        later = _within(model, workspace, remain, target, high - low)
        return _power(model, remain, later, _indicator(np.zeros_like(target)), low)
    k = _steps(bound.value)
    match bound.op:
        case "<=" | "<":
            steps = k if bound.op == "<=" else k - 1
            if steps < 0:  # U<0 can never be met
                return _indicator(np.zeros_like(target))
            return _within(model, workspace, remain, target, steps)
        case ">=" | ">":
            later = until_probs(model, workspace, remain, target)
            zero = _indicator(np.zeros_like(target))
            return _power(model, remain, later, zero, k if bound.op == ">=" else k + 1)
    raise CheckError(f"step bound '{bound.op}' is not allowed on U, F or G", bound.span)


def _within(model: ExactDTMC, workspace: Workspace, remain: BoolArray, target: BoolArray,
            steps: int) -> ObjectArray:
    """Exact probability of ``remain U<=steps target``."""
    hit = _indicator(target)
    return _power(model, remain & ~target, hit, hit, steps)


def until_probs(model: ExactDTMC, workspace: Workspace, remain: BoolArray,
                target: BoolArray) -> ObjectArray:
    """Exact probability of ``remain U target``: pre-pass, then the SCC-wise solve."""
    P = model.dtmc.transitions
    no = kernels.prob0(P, remain, target, workspace=workspace)
    yes = kernels.prob1(P, remain, target, no, workspace=workspace)
    result = _indicator(yes)
    maybe = ~(no | yes)
    if maybe.any():
        rows = np.flatnonzero(maybe)
        b = row_products(P, model.probabilities, rows, _indicator(yes))
        result[rows] = solve(_system(model, workspace, maybe), b)
    return result


def _system(model: ExactDTMC, workspace: Workspace, maybe: BoolArray) -> Prepared:
    """The system on *maybe*, prepared once per model, mask and workspace (rewards share
    targets)."""
    kept = workspace.kernels.exact(model.dtmc.transitions)
    key = np.packbits(maybe).tobytes()
    found = kept.get(key)
    if not isinstance(found, Prepared):
        found = prepare(restrict(model.dtmc.transitions, model.probabilities, maybe))
        kept[key] = found
    return found


def _next(model: ExactDTMC, target: BoolArray) -> ObjectArray:
    everything = np.arange(model.dtmc.num_states)
    return row_products(model.dtmc.transitions, model.probabilities, everything,
                        _indicator(target))


def _power(model: ExactDTMC, moving: BoolArray, start: ObjectArray, offset: ObjectArray,
           k: int) -> ObjectArray:
    """``k`` steps of ``x <- offset + M x`` (M: the rows of *moving*), stopping at a fixpoint."""
    P, probabilities = model.dtmc.transitions, model.probabilities
    rows = np.flatnonzero(moving)
    x = start.copy()
    for _ in range(k):
        following = offset.copy()
        following[rows] = following[rows] + row_products(P, probabilities, rows, x)
        if np.all(following == x):
            break
        x = following
    return x


def _indicator(mask: BoolArray) -> ObjectArray:
    result: ObjectArray = np.where(mask, _ONE, _ZERO).astype(object)
    return result


# ---------------------------------------------------------------------------
# Rewards
# ---------------------------------------------------------------------------


def path_rewards(model: ExactDTMC, workspace: Workspace, op: RewardOp) -> ExactValues:
    """Per-state exact expected reward of ``R{..}`` over ``F``, ``C<=k`` or ``I=k``."""
    structure = _reward_structure(model, op)
    zero = _indicator(np.zeros(model.dtmc.num_states, dtype=bool))
    everywhere = np.ones(model.dtmc.num_states, dtype=bool)
    match op.path:
        case Reach(target=target):
            reached = state_set(model, workspace, target)
            return reach_rewards(model, workspace, structure.total, reached)
        case Cumulative(bound=bound):
            total = structure.total
            return ExactValues.finite(_power(model, everywhere, zero, total, _steps(bound)))
        case Instantaneous(time=time_):
            state = structure.state
            return ExactValues.finite(_power(model, everywhere, state, zero, _steps(time_)))
        case ConditionalReach():
            from veribattery.checker import exact_storm_formulas as storm

            return storm.conditional_reach_rewards(model, workspace, structure, op.path)
    raise UndefinedResult(
        f"{type(op.path).__name__} reward paths are not supported in exact arithmetic",
        op.path.span)


def reach_rewards(model: ExactDTMC, workspace: Workspace, rewards: ObjectArray,
                  target: BoolArray) -> ExactValues:
    """Exact ``R=? [F target]``: infinite where *target* is not almost sure (PRISM)."""
    P = model.dtmc.transitions
    everywhere = np.ones(P.shape[0], dtype=bool)
    no = kernels.prob0(P, everywhere, target, workspace=workspace)
    sure = kernels.prob1(P, everywhere, target, no, workspace=workspace)
    result = _indicator(np.zeros_like(target))
    maybe = sure & ~target
    if maybe.any():
        rows = np.flatnonzero(maybe)
        result[rows] = solve(_system(model, workspace, maybe), rewards[rows])
    return ExactValues(result, ~sure)


def _reward_structure(model: ExactDTMC, op: RewardOp) -> ExactRewards:
    try:
        return model.reward(op.reward)
    except (KeyError, IndexError):
        key = "" if op.reward is None else f" {op.reward!r}"
        raise CheckError(f"the model has no reward structure{key}", op.span) from None
