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
or reward bounds still use the product chain (:func:`conditioned_chain`), whose
results are reported with their range only (not certified).

States from which *b* is unreachable have no conditioned chain; their value is NaN.
"""

from __future__ import annotations

import weakref
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker import certify, kernels, linsolve
from veribattery.checker.bounds import Bounds
from veribattery.errors import CheckError, Span, UndefinedResult
from veribattery.explore.dtmc import DTMC, RewardVectors


class ConditionUnreachable(UndefinedResult):
    """The condition of a conditional property has probability 0 from the initial state."""


@dataclass(frozen=True, slots=True)
class ConditionedChain:
    """The conditioned DTMC of a model given ``F b``, and where each state starts in it.

    :param dtmc: the product chain (copy 0 then copy 1), with the original variables,
        labels and reward structures carried over to each copy.
    :param start: for each original state, its index in *dtmc*, or -1 where
        ``P(F b) = 0``.
    :param origin: for each product state, the original state it copies.
    :param condition: ``P(F b)`` in each original state.
    """

    dtmc: DTMC
    start: IntArray
    origin: IntArray
    condition: FloatArray

    def lift(self, values: FloatArray) -> FloatArray:
        """Values over the product chain → values of the original states (NaN: undefined)."""
        result = np.full(self.start.size, np.nan)
        defined = self.start >= 0
        result[defined] = values[self.start[defined]]
        return result


def conditioned_chain(dtmc: DTMC, condition: BoolArray) -> ConditionedChain:
    """The chain of *dtmc* conditioned on eventually reaching *condition*.

    :param dtmc: the model.
    :param condition: the states *b* of the condition ``F b``.
    """
    P = dtmc.transitions
    n = dtmc.num_states
    x = kernels.until_probs(P, np.ones(n, dtype=bool), condition).value
    before = (x > 0) & ~condition
    after = _reachable_from(P, condition)
    origin = np.concatenate([np.flatnonzero(before), np.flatnonzero(after)])
    index0 = _index_map(before)
    index1 = _index_map(after)
    matrix = sp.vstack([_conditioned_rows(P, before, condition, x, index0, index1, origin.size),
                        _shifted_rows(P, after, index1, int(before.sum()), origin.size)])
    start = np.full(n, -1, dtype=np.int64)
    start[before] = index0[before]
    start[condition] = index1[condition] + int(before.sum())
    product = _carry_over(dtmc, sp.csr_matrix(matrix), origin, start)
    return ConditionedChain(product, start, origin, x)


def _reachable_from(P: CsrMatrix, seeds: BoolArray) -> BoolArray:
    """States reachable from *seeds* (the seeds included): one search in C."""
    n = P.shape[0]
    seed_idx = np.flatnonzero(seeds)
    rows = np.repeat(np.arange(n), np.diff(P.indptr))
    keep = P.data > 0
    src = np.concatenate([rows[keep], np.full(seed_idx.size, n)])
    dst = np.concatenate([P.indices[keep], seed_idx])
    graph = sp.csr_matrix((np.ones(src.size), (src, dst)), shape=(n + 1, n + 1))
    order = csgraph.breadth_first_order(graph, n, directed=True, return_predecessors=False)
    reached = np.zeros(n + 1, dtype=bool)
    reached[order] = True
    return reached[:n]


def _index_map(mask: BoolArray) -> IntArray:
    """Position of each masked state among the masked ones; -1 elsewhere."""
    index = np.full(mask.size, -1, dtype=np.int64)
    index[mask] = np.arange(int(mask.sum()))
    return index


def _conditioned_rows(P: CsrMatrix, before: BoolArray, condition: BoolArray, x: FloatArray,
                      index0: IntArray, index1: IntArray, size: int) -> sp.csr_matrix:
    """Copy 0: ``P(s,t) x(t) / x(s)``, into copy 1 where *t* meets the condition."""
    rows = sp.coo_matrix(P[before])
    keep = x[rows.col] > 0
    r, c = rows.row[keep], rows.col[keep]
    weights = rows.data[keep] * x[c]
    columns = np.where(condition[c], index1[c] + int(before.sum()), index0[c])
    # Normalise each row to sum 1 exactly (x solves the system only to rounding).
    sums = np.bincount(r, weights=weights, minlength=int(before.sum()))
    matrix = sp.csr_matrix((weights / sums[r], (r, columns)),
                           shape=(int(before.sum()), size))
    matrix.sum_duplicates()
    return matrix


def _shifted_rows(P: CsrMatrix, after: BoolArray, index1: IntArray, offset: int,
                  size: int) -> sp.csr_matrix:
    """Copy 1: the original rows of the states reachable from the condition."""
    rows = sp.coo_matrix(P[after])
    columns = index1[rows.col] + offset
    return sp.csr_matrix((rows.data, (rows.row, columns)), shape=(int(after.sum()), size))


def _carry_over(dtmc: DTMC, matrix: CsrMatrix, origin: IntArray, start: IntArray) -> DTMC:
    """The product DTMC: each product state has the variables, labels, rewards of its origin."""
    initial = start[dtmc.initial]
    return DTMC(
        transitions=matrix,
        states=dtmc.states[origin],
        variable_names=dtmc.variable_names,
        initial=initial[initial >= 0],
        labels={name: mask[origin] for name, mask in dtmc.labels.items()},
        rewards=tuple(RewardVectors(r.name, r.state[origin], r.transition[origin])
                      for r in dtmc.rewards),
    )


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


#: Conditions kept per process: (matrix, mask) → Condition, the matrix held weakly.
_KEPT = 4
_CONDITIONS: OrderedDict[tuple[int, bytes], tuple[weakref.ref[CsrMatrix], Condition]] = (
    OrderedDict())


def condition_probs(P: CsrMatrix, states: BoolArray) -> Condition:
    """``P(F states)`` on *P*, computed once per matrix and condition.

    :param P: row-stochastic CSR transition matrix (not modified afterwards).
    :param states: the states *b* of the condition ``F b``.
    """
    key = (id(P), np.packbits(states).tobytes() + states.size.to_bytes(8, "little"))
    kept = _CONDITIONS.get(key)
    if kept is not None and kept[0]() is P:
        _CONDITIONS.move_to_end(key)
        return kept[1]
    everywhere = np.ones(P.shape[0], dtype=bool)
    found = Condition(states.copy(), kernels.until_probs(P, everywhere, states),
                      ~kernels.prob0(P, everywhere, states))
    _CONDITIONS[key] = (weakref.ref(P), found)
    while len(_CONDITIONS) > _KEPT:
        _CONDITIONS.popitem(last=False)
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
                condition: Condition) -> Bounds:
    """``P(remain U target | F b)`` per state, certified (NaN where ``F b`` is impossible).

    The numerator ``z = P(remain U target ∧ F b)`` is 0 or known once the path meets
    *target* (then ``z = x``), leaves *remain* (0) or meets *b* (then ``z = P(remain U
    target)``): an absorption problem on the other states (:func:`kernels.absorption`).
    """
    until = kernels.until_probs(P, remain, target)
    b = condition.states
    x = condition.probs
    fixed = target | b | ~remain
    known = tuple(np.where(target, xv, np.where(b, uv, 0.0)) for xv, uv in
                  ((x.value, until.value), (x.lower, until.lower), (x.upper, until.upper)))
    numerator = kernels.absorption(P, fixed, Bounds(*known))
    return divide(numerator, condition, 1.0)


def next_given(P: CsrMatrix, target: BoolArray, condition: Condition) -> Bounds:
    """``P(X target | F b)``: ``sum_t P(s,t) [t in target] x(t)`` outside *b*, ``P(X target)``
    on *b* (there the condition already holds), divided by ``x``."""
    x = condition.probs
    hits = target.astype(np.float64)
    value = np.asarray(P @ (hits * x.value), dtype=np.float64)
    lower = certify.enclose_product(P, hits * x.lower)[1]
    upper = certify.enclose_product(P, hits * x.upper)[2]
    on_b = kernels.next_probs(P, target)
    b = condition.states
    numerator = Bounds.around(np.where(b, on_b.value, value), np.where(b, on_b.lower, lower),
                              np.where(b, on_b.upper, upper))
    return divide(Bounds(*(np.maximum(v, 0.0) for v in
                           (numerator.value, numerator.lower, numerator.upper))),
                  condition, 1.0)


def reach_rewards_given(P: CsrMatrix, rewards: FloatArray, target: BoolArray,
                        condition: Condition, focus_states: IntArray | None = None) -> Bounds:
    """``E[reward until target | F b]`` per state, certified (``R=? [ F a || F b ]``).

    The numerator ``y = E[R · 1{F b}]`` is 0 on *target*; on *b* the condition holds
    already, so ``y = R=? [ F target ]`` there (infinite where *target* is not almost
    sure); it is infinite where a path outside *target* reaches such a *b* state;
    elsewhere it solves ``y = r x + P y`` (the reward of a step from a state before
    *b* counts on the paths that go on to meet *b*: a fraction ``x`` of them).
    With *focus_states*, the numerator's bounds may be trivial away from them
    (``kernels.until_probs``); the condition's are always whole, for its offset.
    """
    b = condition.states & ~target
    # On b the unconditional value (not needed when b lies inside the target, as
    # the mission's success inside done).
    if b.any():
        plain = kernels.reach_rewards(P, rewards, target)
        infinite = ~kernels.prob0(P, ~target, b & np.isinf(plain.value))
        known = Bounds(*(np.where(b & ~infinite, v, 0.0) for v in
                         (plain.value, plain.lower, plain.upper)))
        del plain
    else:  # no known values: one zero vector stands for all three during the solve
        infinite = ~kernels.prob0(P, ~target, b)
        zero = np.zeros(P.shape[0])
        known = Bounds(zero, zero, zero)
    allowed = ~infinite & ~target & ~b
    maybe = allowed & condition.possible
    found = (_reward_system(P, rewards, (maybe, allowed), condition.probs, known,
                            focus_states) if maybe.any() else None)
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
                   x: Bounds, known: Bounds, focus_states: IntArray | None) -> Bounds:
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
    system = kernels.shared_system(P, maybe, allowed)
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
    found = kernels.quick_bounds(F, solver, rhs.astype(np.float64), np.full((), floor),
                                 np.full((), np.inf), kernels.focus_rows(system, F, focus_states))
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
        rhs += linsolve.extended_product(rows, known)
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


def _long_way(F: certify.AffineMap, solver: linsolve.Factorization,
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
                                                  lambda b: b.precise_states())
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


def _solve(solver: linsolve.Factorization, b: npt.NDArray[np.floating]) -> FloatArray | None:
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
                       what: str, span: Span) -> FloatArray:
    """Per-state value of *objective* given ``F condition`` on the product chain, NaN where
    that is impossible (the fallback for objectives with step or reward bounds).

    :param dtmc: the model.
    :param condition: the states of the condition ``F b``.
    :param objective: computes the objective's per-state values on the conditioned
        chain (``chain.dtmc``).
    :param what: how to name the condition in an error, e.g. ``F "success"``.
    :param span: where the conditional formula is.
    :raises ConditionUnreachable: when the condition has probability 0 from an initial state.
    """
    require_possible(condition_probs(dtmc.transitions, condition), dtmc.initial, what, span)
    chain = conditioned_chain(dtmc, condition)
    return chain.lift(objective(chain))


def conditional_reach_reward_bounds(dtmc: DTMC, rewards: RewardVectors, target: BoolArray,
                                    condition: BoolArray, what: str, span: Span,
                                    focus_states: IntArray | None = None) -> Bounds:
    """``R=? [ F target || F condition ]`` per state, certified (NaN where impossible).

    :param dtmc: the model.
    :param rewards: the reward structure.
    :param target: the states to reach.
    :param condition: the states of the condition.
    :param what: how to name the condition in an error.
    :param span: where the formula is.
    :param focus_states: as for ``kernels.until_probs``.
    :raises ConditionUnreachable: when the condition has probability 0 from an initial state.
    """
    found = condition_probs(dtmc.transitions, condition)
    require_possible(found, dtmc.initial, what, span)
    return reach_rewards_given(dtmc.transitions, rewards.total, target, found, focus_states)


def conditional_reach_rewards(dtmc: DTMC, rewards: RewardVectors, target: BoolArray,
                              condition: BoolArray, what: str, span: Span) -> FloatArray:
    """The point values of :func:`conditional_reach_reward_bounds`."""
    return conditional_reach_reward_bounds(dtmc, rewards, target, condition, what, span).value
