"""Conditional properties: Storm's ``P=? [ phi || F b ]`` and ``R=? [ F a || F b ]``.

The value is that of the objective on the chain conditioned on ``F b`` (Doob's
h-transform), computed without building that chain as a ratio of two certified
quantities of the original chain (``docs/numerics.md``, "Conditional results"):

* ``P(phi | F b) = P(phi ∧ F b) / P(F b)``; for ``phi = c U a`` the numerator is
  an absorption problem with known values on ``a`` (``P(F b)``), on ``b`` (``P(c U a)``)
  and 0 on ``!c``; ``G``, ``W``, ``R`` are complements of an until given ``F b``,
  and ``X`` is one enclosed product;
* ``E[R_a | F b] = E[R_a · 1{F b}] / P(F b)``, the numerator a reach-reward system
  with reward ``r · P(F b)`` per state, infinite where a path may reach *b* and
  then avoid *a* forever with positive probability (PRISM's convention, on the
  conditioned chain).

``x = P(F b)`` is the unconditional until (memoised per matrix and condition, so
the two conditional mission defaults solve it once), and the reward numerator
solves on the same states as ``R=? [ F a ]`` (sharing its factorisation) — one
extra solve of size *n*, not a product chain of size 2n. Objectives with step
or reward bounds still use the product chain
(:func:`~veribattery.checker.kernels.conditioned.conditioned_chain`), whose
results are reported with their range only (not certified).

States from which *b* is unreachable have no conditioned chain; their value is NaN.
"""

from __future__ import annotations

import weakref
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker import certify, linalg
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.kernels.conditioned import conditioned_chain
from veribattery.checker.kernels.prepass import prob0
from veribattery.checker.kernels.steps import absorption, next_probs
from veribattery.checker.kernels.systems import shared_system
from veribattery.checker.kernels.until import focus_rows, quick_bounds, reach_rewards, until_probs
from veribattery.errors import CheckError, Span, UndefinedResult
from veribattery.explore.dtmc import DTMC, RewardVectors

if TYPE_CHECKING:
    from veribattery.checker.kernels.conditioned import ConditionedChain
    from veribattery.checker.workspace import Workspace


class ConditionUnreachable(UndefinedResult):
    """The condition of a conditional property has probability 0 from the initial state."""

# ---------------------------------------------------------------------------
# The condition: P(F b), certified and memoised
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Condition:
    """``x = P(F b)`` per state with certified bounds, and where it is positive.

    :param states: the states *b*.
    :param probs: ``P(F b)`` per state.
    :param possible: ``P(F b) > 0`` (a graph search, exact).
    """

    states: BoolArray
    probs: Bounds
    possible: BoolArray


#: Conditions a :class:`Conditions` keeps.
_KEPT = 4


class Conditions:
    """The conditions ``P(F b)`` computed last, held by a
    :class:`~veribattery.checker.workspace.Workspace`: (matrix, mask) → Condition, the
    matrix held weakly (the two conditional mission defaults share one)."""

    def __init__(self) -> None:
        self.kept: OrderedDict[tuple[int, bytes], tuple[weakref.ref[CsrMatrix], Condition]] = (
            OrderedDict())

    @property
    def empty(self) -> bool:
        """Whether nothing is kept yet."""
        return not self.kept


def condition_probs(P: CsrMatrix, states: BoolArray, *, workspace: Workspace) -> Condition:
    """``P(F states)`` on *P*, computed once per matrix, condition and workspace.

    :param P: row-stochastic CSR transition matrix (not modified afterwards).
    :param states: the states *b* of the condition ``F b``.
    :param workspace: where the condition (and the checker's memos) are kept.
    """
    conditions = workspace.conditions.kept
    key = (id(P), np.packbits(states).tobytes() + states.size.to_bytes(8, "little"))
    kept = conditions.get(key)
    if kept is not None and kept[0]() is P:
        conditions.move_to_end(key)
        return kept[1]
    everywhere = np.ones(P.shape[0], dtype=bool)
    found = Condition(states.copy(), until_probs(P, everywhere, states,
                                                         workspace=workspace),
                      ~prob0(P, everywhere, states, workspace=workspace))
    conditions[key] = (weakref.ref(P), found)
    while len(conditions) > _KEPT:
        conditions.popitem(last=False)
    return found


def require_possible(condition: Condition, initial: IntArray, what: str, span: Span) -> None:
    """:raises ConditionUnreachable: when the condition has probability 0 from an initial state."""
    if not condition.possible[initial].all():
        raise ConditionUnreachable(f"the condition {what} has probability 0 from the initial "
                                   "state, so the conditional value is undefined", span)


def divide(numerator: Bounds, condition: Condition, ceiling: float) -> Bounds:
    """``numerator / P(F b)`` with outward rounding, clipped to ``[0, ceiling]``; NaN where
    the condition is impossible.

    ``[a, b] / [c, d]`` with ``0 <= a`` and ``0 < c`` is ``[a/d, b/c]``; each quotient
    is rounded once (to nearest), so one step outward covers it (``certify.step_down``
    and ``step_up``: at least one ulp, without a libm call per entry). Infinite numerators
    stay infinite.
    """
    x = condition.probs
    # Each vector is made once and then edited in place (at 1.4M states every
    # temporary is 11 MB, and this runs at the conditional properties' peak).
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        value = numerator.value / x.value
        lower = certify.step_down(numerator.lower / x.upper)
        kept = np.isinf(numerator.lower)
        lower[kept] = numerator.lower[kept]
        upper = certify.step_up(numerator.upper / x.lower)
        kept = np.isinf(numerator.upper) | (numerator.upper == 0)
        upper[kept] = numerator.upper[kept]
    del kept
    upper[np.isnan(upper)] = np.inf  # a lower bound of x of 0
    np.maximum(lower, 0.0, out=lower)
    np.minimum(upper, ceiling, out=upper)
    # The value moved into [lower, upper] (Bounds.around), NaN where x was 0.
    unknown = np.isnan(value)
    value[unknown] = lower[unknown]
    del unknown
    np.maximum(value, lower, out=value)
    np.minimum(value, upper, out=value)
    undefined = ~condition.possible
    value[undefined] = lower[undefined] = upper[undefined] = np.nan
    return Bounds(value, lower, upper)


# ---------------------------------------------------------------------------
# Numerators: P(phi ∧ F b) and E[R · 1{F b}]
# ---------------------------------------------------------------------------


def until_given(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                condition: Condition, *, workspace: Workspace) -> Bounds:
    """``P(remain U target | F b)`` per state, certified (NaN where ``F b`` is impossible).

    The numerator ``z = P(remain U target ∧ F b)`` is 0 or known once the path meets
    *target* (then ``z = x``), leaves *remain* (0) or meets *b* (then ``z = P(remain U
    target)``): an absorption problem on the other states (:func:`steps.absorption`).
    """
    until = until_probs(P, remain, target, workspace=workspace)
    b = condition.states
    x = condition.probs
    fixed = target | b | ~remain
    known = tuple(np.where(target, xv, np.where(b, uv, 0.0)) for xv, uv in
                  ((x.value, until.value), (x.lower, until.lower), (x.upper, until.upper)))
    numerator = absorption(P, fixed, Bounds(*known), workspace=workspace)
    return divide(numerator, condition, 1.0)


def next_given(P: CsrMatrix, target: BoolArray, condition: Condition) -> Bounds:
    """``P(X target | F b)``: ``sum_t P(s,t) [t in target] x(t)`` outside *b*, ``P(X target)``
    on *b* (there the condition already holds), divided by ``x``."""
    x = condition.probs
    hits = target.astype(np.float64)
    value = np.asarray(P @ (hits * x.value), dtype=np.float64)
    lower = certify.enclose_product(P, hits * x.lower)[1]
    upper = certify.enclose_product(P, hits * x.upper)[2]
    on_b = next_probs(P, target)
    b = condition.states
    numerator = Bounds.around(np.where(b, on_b.value, value), np.where(b, on_b.lower, lower),
                              np.where(b, on_b.upper, upper))
    return divide(Bounds(*(np.maximum(v, 0.0) for v in
                           (numerator.value, numerator.lower, numerator.upper))),
                  condition, 1.0)


def reach_rewards_given(P: CsrMatrix, rewards: FloatArray, target: BoolArray,
                        condition: Condition, focus_states: IntArray | None = None, *,
                        workspace: Workspace) -> Bounds:
    """``E[reward until target | F b]`` per state, certified (``R=? [ F a || F b ]``).

    The numerator ``y = E[R · 1{F b}]`` is 0 on *target*; on *b* the condition holds
    already, so ``y = R=? [ F target ]`` there (infinite where *target* is not almost
    sure); it is infinite where a path outside *target* reaches such a *b* state;
    elsewhere it solves ``y = r x + P y`` (the reward of a step from a state before
    *b* counts on the paths that go on to meet *b*: a fraction ``x`` of them).
    With *focus_states*, the numerator's bounds may be trivial away from them
    (``until.until_probs``); the condition's are always whole, for its offset.
    """
    b = condition.states & ~target
    # On b the unconditional value (not needed when b lies inside the target, as
    # the mission's success inside done).
    if b.any():
        plain = reach_rewards(P, rewards, target, workspace=workspace)
        infinite = ~prob0(P, ~target, b & np.isinf(plain.value), workspace=workspace)
        known = Bounds(*(np.where(b & ~infinite, v, 0.0) for v in
                         (plain.value, plain.lower, plain.upper)))
        del plain
    else:  # no known values: one zero vector stands for all three during the solve
        infinite = ~prob0(P, ~target, b, workspace=workspace)
        zero = np.zeros(P.shape[0])
        known = Bounds(zero, zero, zero)
    allowed = ~infinite & ~target & ~b
    maybe = allowed & condition.possible
    found = (_reward_system(P, rewards, (maybe, allowed), condition.probs, known,
                            focus_states, workspace) if maybe.any() else None)
    # The numerator: inf where infinite, the solution on maybe (which lies outside
    # infinite), the known values elsewhere.
    vectors = [known.value.copy(), known.lower.copy(), known.upper.copy()]
    del known
    for vector, part in zip(vectors, (None, None, None) if found is None else
                            (found.value, found.lower, found.upper), strict=True):
        vector[infinite] = np.inf
        if part is not None:
            vector[maybe] = part
    del found
    if focus_states is None:
        return divide(Bounds(*vectors), condition, np.inf)
    return _divided_at(Bounds(*vectors), condition, focus_states)


def _divided_at(numerator: Bounds, condition: Condition, focus_states: IntArray) -> Bounds:
    """:func:`divide` (an expectation: no ceiling) at *focus_states* only; elsewhere the
    trivial bounds ``[0, inf]`` and a value of 0, as the numerator's own there."""
    part = divide(numerator.at(focus_states),
                  Condition(condition.states[focus_states], condition.probs.at(focus_states),
                            condition.possible[focus_states]), np.inf)
    n = numerator.value.size
    found = Bounds(np.zeros(n), np.zeros(n), np.full(n, np.inf))
    for whole, piece in zip((found.value, found.lower, found.upper),
                            (part.value, part.lower, part.upper), strict=True):
        whole[focus_states] = piece
    return found


def _reward_system(P: CsrMatrix, rewards: FloatArray, states: tuple[BoolArray, BoolArray],
                   x: Bounds, known: Bounds, focus_states: IntArray | None,
                   workspace: Workspace) -> Bounds:
    """The certified solution of ``y = r x + P y`` on *maybe*, *known* elsewhere.

    The offset ``r x`` is only known as an interval, so the lower bound is certified
    for the map with offset ``r x_lower`` stepped down (and the known values' lower
    bounds) and the upper for ``r x_upper`` stepped up: the fixed point is monotone in
    both. Every state of *maybe* leaves it almost surely (a bottom component inside
    it would hold a *b* state), so the fixed point is unique.

    The equation also holds, with ``y = 0``, on the states of *allowed* where the
    condition is impossible (``x = 0`` there and on every successor), so a kept system
    on a superset of *maybe* inside *allowed* (``R=? [ F a ]``'s) is solved instead.
    """
    maybe, allowed = states
    system = shared_system(P, maybe, allowed, workspace=workspace)
    unknowns = system.unknowns
    r = np.asarray(rewards[unknowns], dtype=np.float64)
    low, high = _offset_bounds(r, x.lower[unknowns], x.upper[unknowns])
    rows, solver = system.rows, system.factorization
    below = system.affine(known.lower, known.lower, low)
    F = _Split.pair(replace(below, known_lower=known.upper, known_upper=known.upper,
                          offset=high), below)
    floor = 0.0 if np.all(low >= 0) else -np.inf
    # The quick path reads the right-hand side in float64 only: the extended one is
    # made again if the long way is needed (8 bytes per state less at the peak).
    rhs = _right_side(rows, known.value, r, x.value[unknowns])
    found = quick_bounds(F, solver, rhs.astype(np.float64), np.full((), floor),
                                 np.full((), np.inf), focus_rows(system, F, focus_states))
    del rhs
    if found is None:
        rhs = _right_side(rows, known.value, r, x.value[unknowns])
        size = rhs.size
        found = _long_way(F, solver, rhs, np.full(size, floor), np.full(size, np.inf))
    where = np.flatnonzero(maybe[unknowns])
    return Bounds(found.value[where], found.lower[where], found.upper[where])


def _right_side(rows: CsrMatrix, known: FloatArray, r: FloatArray,
                x: FloatArray) -> npt.NDArray[np.longdouble]:
    """``r x + P known`` in extended precision (rows widened a block at a time)."""
    rhs = (r * x).astype(np.longdouble)
    if known.any():  # (zero when b lies inside the target: the mission's success in done)
        rhs += linalg.extended_product(rows, known)
    return rhs


def _offset_bounds(r: FloatArray, x_lower: FloatArray, x_upper: FloatArray
                   ) -> tuple[FloatArray, FloatArray]:
    """Certified bounds of the offset ``r x`` from those of *x*: each product stepped
    outward (``certify.step_down``/``step_up``), except where it is exact (``x = 1`` or
    ``r = 0``)."""
    one, two = r * x_lower, r * x_upper
    exact = (x_lower == 1.0) | (r == 0)
    smaller = np.minimum(one, two)
    low = np.where(exact, smaller, certify.step_down(smaller))
    del smaller
    # r x >= 0 exactly where both are: rounding down must not leave 0 (x = 0 where the
    # condition is impossible), or the map looks signed and loses its fast images.
    low = np.where((r >= 0) & (x_lower >= 0), np.maximum(low, 0.0), low)
    larger = np.maximum(one, two)
    del one, two
    high = np.where(exact, larger, certify.step_up(larger))
    return low, high


def _long_way(F: certify.AffineMap, solver: linalg.Factorization,
              rhs: npt.NDArray[np.floating],
              floor: FloatArray, ceiling: FloatArray) -> Bounds:
    """The refined solve, certified, then interval iteration if still too wide."""
    point = _solve(solver, rhs)
    if point is None:
        point, lower, upper = floor.copy(), floor, ceiling
    else:
        lower, upper = certify.certify_fixpoint(F, point, solver.correction, floor, ceiling)
    found = Bounds.around(point, lower, upper)
    if not found.precise_states().all():
        lower, upper = certify.interval_iteration(F, lower, upper, point,
                                                  lambda b: b.precise_states(), solver.monitor)
        found = Bounds.around(point, lower, upper)
    return found


@dataclass(frozen=True, slots=True)
class _Split(certify.AffineMap):
    """Two monotone maps that enclose the exact one: upper bounds from this one
    (largest offset and known values), lower bounds from *below* (smallest)."""

    below: certify.AffineMap | None = None

    @classmethod
    def pair(cls, above: certify.AffineMap, below: certify.AffineMap) -> _Split:
        parts: dict[str, Any] = {f.name: getattr(above, f.name) for f in fields(certify.AffineMap)}
        return cls(**parts, below=below)

    def lower(self, x: FloatArray) -> FloatArray:
        assert self.below is not None
        return self.below.lower(x)

    @property
    def nonnegative(self) -> bool:
        assert self.below is not None
        return certify.AffineMap.nonnegative.fget(self) and self.below.nonnegative  # type: ignore[attr-defined]

    def images(self, low: FloatArray, high: FloatArray) -> tuple[FloatArray, FloatArray]:
        assert self.below is not None
        return self.below.image(low, up=False), certify.AffineMap.image(self, high, up=True)

    def constant_side(self, *, up: bool) -> FloatArray:
        assert self.below is not None
        return certify.AffineMap.constant_side(self, up=True) if up else (
            self.below.constant_side(up=False))


def _solve(solver: linalg.Factorization, b: npt.NDArray[np.floating]) -> FloatArray | None:
    """The fast path's approximate solution (None when no solver was accepted)."""
    try:
        return solver.solve(b.astype(np.longdouble))
    except CheckError:
        return None


# ---------------------------------------------------------------------------
# Entry points for the PCTL recursion (it passes masks and a callback, no nodes)
# ---------------------------------------------------------------------------


def conditional_values(dtmc: DTMC, condition: BoolArray,
                       objective: Callable[[ConditionedChain], FloatArray],
                       what: str, span: Span, *, workspace: Workspace) -> FloatArray:
    """Per-state value of *objective* given ``F condition`` on the product chain, NaN where
    that is impossible (the fallback for objectives with step or reward bounds).

    :param dtmc: the model.
    :param condition: the states of the condition ``F b``.
    :param objective: computes the objective's per-state values on the conditioned
        chain (``chain.dtmc``).
    :param what: how to name the condition in an error, e.g. ``F "success"``.
    :param span: where the conditional formula is.
    :param workspace: where the checker's memos are kept.
    :raises ConditionUnreachable: when the condition has probability 0 from an initial state.
    """
    require_possible(condition_probs(dtmc.transitions, condition, workspace=workspace),
                     dtmc.initial, what, span)
    chain = conditioned_chain(dtmc, condition, workspace=workspace)
    return chain.lift(objective(chain))


def conditional_reach_reward_bounds(dtmc: DTMC, rewards: RewardVectors, target: BoolArray,
                                    condition: BoolArray, what: str, span: Span,
                                    focus_states: IntArray | None = None, *,
                                    workspace: Workspace) -> Bounds:
    """``R=? [ F target || F condition ]`` per state, certified (NaN where impossible).

    :param dtmc: the model.
    :param rewards: the reward structure.
    :param target: the states to reach.
    :param condition: the states of the condition.
    :param what: how to name the condition in an error.
    :param span: where the formula is.
    :param focus_states: as for ``until.until_probs``.
    :param workspace: where the checker's memos are kept.
    :raises ConditionUnreachable: when the condition has probability 0 from an initial state.
    """
    found = condition_probs(dtmc.transitions, condition, workspace=workspace)
    require_possible(found, dtmc.initial, what, span)
    return reach_rewards_given(dtmc.transitions, rewards.total, target, found, focus_states,
                               workspace=workspace)


def conditional_reach_rewards(dtmc: DTMC, rewards: RewardVectors, target: BoolArray,
                              condition: BoolArray, what: str, span: Span, *,
                              workspace: Workspace) -> FloatArray:
    """The point values of :func:`conditional_reach_reward_bounds`."""
    return conditional_reach_reward_bounds(dtmc, rewards, target, condition, what, span,
                                           workspace=workspace).value
