"""Step-bounded kernels: next, bounded until, cumulative and instantaneous rewards.

Each iterates one sparse matrix-vector product per step, plus one on the error
radius, and stops early only at an exact fixpoint of the float map (the next iterate
equal to the current one in every bit) or, for a step bound too large to iterate, as
:mod:`~veribattery.checker.certify.horizon` says. :func:`absorption` finishes a system
whose values are known outside it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker import certify
from veribattery.checker.certify import horizon
from veribattery.checker.certify.bounds import (
    Bounds,
    current_precision,
    escalated,
    round_down,
    round_up,
)
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.certify.horizon import Trend
from veribattery.checker.kernels.prepass import prob0
from veribattery.checker.kernels.systems import _restrict, _system
from veribattery.checker.kernels.until import _certified, _spread, until_probs

if TYPE_CHECKING:
    from veribattery.checker.workspace import Workspace


# ---------------------------------------------------------------------------
# Step-bounded kernels: iterate, carrying a rigorous forward error bound
# ---------------------------------------------------------------------------


def _step_power(M: CsrMatrix, start: Bounds, offset: FloatArray, k: int,
                progress: Progress | None = None, trend: Trend = horizon.NONNEGATIVE) -> Bounds:
    """``k`` steps of ``x <- offset + M x`` from *start*, with a certified radius.

    The radius *e* bounds ``|x - exact|`` componentwise: ``e <- M e + delta`` where
    *delta* bounds the rounding of the step (:func:`certify.enclose_product`).
    The iteration stops early at an exact fixpoint of the float map (:func:`_settled`).
    A bound beyond :data:`horizon.ROUND_LIMIT` runs at most :func:`horizon.rounds`
    rounds, the steps left enclosed by what *trend* knows of the exact iterates.
    *progress* (if someone listens) is told ``(steps done, k, "steps")`` after each step.
    """
    if escalated() and np.array_equal(start.lower, start.upper):
        # Asked for exact bounds: iterate in rational arithmetic when small enough.
        from veribattery.checker.linalg import rational

        exact = rational.power_exact(M, start.value, offset, k)
        if exact is not None:
            return Bounds(*exact)
    terms = certify.row_terms(M)
    if k <= horizon.ROUND_LIMIT:
        normwise = _step_power_normwise(M, start, offset, k, terms, progress, trend)
        if normwise is not None:
            return normwise
    x = start.value
    radius = np.maximum(round_up(x - start.lower), round_up(start.upper - x))
    budget = horizon.rounds(k, M.nnz)
    for step in range(budget):
        following, low, high = certify.enclose_product(M, x, offset, terms)
        with np.errstate(invalid="ignore"):  # inf - inf beyond the doubles: NaN, unbounded
            rounding = np.maximum(high - following, following - low)
        if not bool(np.all(np.isfinite(following))):
            # beyond the doubles (a reward sum): what the trend knows from the last step
            return horizon.beyond(following, _lower(x, radius), trend)
        carried = _gained(M, trend, step, k, (x, radius), (following, rounding))
        if carried is not None:
            return carried
        if np.array_equal(following, x):
            fixpoint = _Fixpoint(x, radius, rounding, terms)
            return _settled(M, fixpoint, k - step, budget - step, trend)
        radius = round_up(certify.enclose_product(M, radius, rounding, terms)[2])
        x = following
        if progress is not None:
            progress(step + 1, k, "steps")
        if horizon.checkpoint(step + 1, k):
            found = horizon.early(x, _lower(x, radius), trend)
            if found is not None:
                return found
    if budget < k:
        return horizon.beyond(x, _lower(x, radius), trend)
    return _finish(M, x, radius, np.zeros_like(x), 0)


def _step_power_normwise(M: CsrMatrix, start: Bounds, offset: FloatArray, k: int,
                         terms: FloatArray, progress: Progress | None,
                         trend: Trend) -> Bounds | None:
    """:func:`_step_power` with one radius for every state: one product per step
    instead of two (the componentwise radius needs ``M e`` too), or None when that
    radius would not meet the required absolute precision everywhere.

    ``|x_j - exact_j| <= r_j`` for all states gives ``|M (x - exact)| <= ||M||_inf r_j``,
    so ``r <- ||M||_inf r + max(delta)`` (each operation rounded up) bounds every
    state's error after the step; *delta* is the step's rounding as above.
    """
    _, absolute = current_precision()
    x = start.value
    radius = float(np.max(np.maximum(round_up(x - start.lower), round_up(start.upper - x)),
                          initial=0.0))
    rho = max(1.0, certify.spectral_cap(M))
    for step in range(k):
        if not 2 * radius <= absolute:  # (NaN too) the componentwise radius may still be
            return None
        following, low, high = certify.enclose_product(M, x, offset, terms)
        with np.errstate(invalid="ignore"):  # NaN beyond the doubles: the test above fails
            each = np.maximum(high - following, following - low)
            rounding = float(np.max(each, initial=0.0))
        carried = _gained(M, trend, step, k, (x, np.full_like(x, radius)), (following, each))
        if carried is not None:
            return carried
        if np.array_equal(following, x):
            found = _finish(M, x, np.full_like(x, radius), np.full_like(x, rounding), k - step)
            return found if bool(found.precise_states().all()) else None
        grown = math.nextafter(rho * radius, math.inf)  # each operation rounded up
        radius = math.nextafter(grown + rounding, math.inf)
        x = following
        if progress is not None:
            progress(step + 1, k, "steps")
    if not 2 * radius <= absolute:
        return None
    return _finish(M, x, np.full_like(x, radius), np.zeros_like(x), 0)


def _gained(M: CsrMatrix, trend: Trend, step: int, k: int,
            start: tuple[FloatArray, FloatArray], following: tuple[FloatArray, FloatArray]
            ) -> Bounds | None:
    """At a checkpoint of ``C<=k`` (:func:`horizon.gain_checkpoint`), the bounds of step
    *k* carried from step *step* (*start*: value and radius) and the next, computed
    with its rounding (:func:`horizon.gained`), if they meet the precision; else None."""
    if not (trend.gaining and horizon.gain_checkpoint(step + 1, k)):
        return None
    found = horizon.gained(start, following, k - step, horizon.row_sum_bounds(M))
    return found if found is not None and bool(found.precise_states().all()) else None


@dataclass(frozen=True, slots=True)
class _Fixpoint:
    """An iterate *x* that the float map sends to itself: its radius, the rounding
    bound of its step, and the matrix's row terms."""

    x: FloatArray
    radius: FloatArray
    rounding: FloatArray
    terms: FloatArray


def _settled(M: CsrMatrix, at: _Fixpoint, remaining: int, budget: int,
             trend: Trend) -> Bounds:
    """Bounds after *remaining* more steps from a float fixpoint.

    The remaining steps bounded normwise (:func:`_finish`), if precise. Else every
    later step has the same value and rounding, so only the radius moves: it is
    iterated alone (at most *budget* rounds) until what it still moves by, carried
    over the steps left (:func:`horizon.drifted`), is precise or stops narrowing (checked
    after 1, 2, 4, ... rounds), or the steps run out; what is found is narrowed by
    *trend*.
    """
    found = _finish(M, at.x, at.radius, at.rounding, remaining)
    if bool(found.precise_states().all()):
        return found
    rho = max(1.0, certify.spectral_cap(M))
    radius, left, widest = at.radius, remaining, np.inf
    for done in range(1, min(remaining, budget) + 1):
        grown = round_up(certify.enclose_product(M, radius, at.rounding, at.terms)[2])
        if done & (done - 1) == 0 or bool(np.all(grown <= radius)):
            drift = horizon.drifted(radius, grown, rho, left)
            if np.isfinite(widest) and not np.max(drift) < widest:
                break  # no narrower than at the last (finite) check: keep that one
            found, widest = _around(at.x, drift), float(np.max(drift))
            if bool(found.precise_states().all()):
                break
        radius, left = grown, left - 1
    else:
        grown = round_up(certify.enclose_product(M, radius, at.rounding, at.terms)[2])
        found = _around(at.x, horizon.drifted(radius, grown, rho, left))
    return horizon.meet(found, at.x, _lower(at.x, at.radius), trend)


def _lower(x: FloatArray, radius: FloatArray) -> FloatArray:
    """``x - radius`` rounded down; -inf where that is ``inf - inf`` (a value beyond the
    doubles, whose radius is infinite too)."""
    with np.errstate(invalid="ignore"):
        lower = round_down(x - radius)
    return np.where(np.isnan(lower), -np.inf, lower)


def _around(x: FloatArray, radius: FloatArray) -> Bounds:
    """*x* with the radius *radius*, rounded outward (a value beyond the doubles is inf
    with an infinite or NaN radius: no bound then)."""
    with np.errstate(invalid="ignore"):
        upper = round_up(x + radius)
    return Bounds(x, _lower(x, radius), np.where(np.isnan(upper), np.inf, upper))


def _finish(M: CsrMatrix, x: FloatArray, radius: FloatArray, rounding: FloatArray,
            remaining: int) -> Bounds:
    """Bounds after *remaining* more steps at a float fixpoint *x* (normwise)."""
    if remaining:
        rho = max(1.0, certify.spectral_cap(M))
        try:
            growth = rho**remaining
        except OverflowError:
            growth = np.inf
        extra = growth * (float(np.max(radius)) + remaining * float(np.max(rounding)))
        radius = round_up(np.full_like(x, extra)) if extra > 0 else radius
    return _around(x, radius)


def _rows_in(P: CsrMatrix, mask: BoolArray) -> CsrMatrix:
    """*P* with the rows outside *mask* zeroed (those states stop moving)."""
    return sp.csr_matrix(sp.diags(mask.astype(np.float64), format="csr") @ P)


def _probabilities(found: Bounds) -> Bounds:
    """Probabilities: the value clipped to [0, 1], lower bounds to 0.

    Upper bounds are not clipped to 1: a stored row may sum to a little more
    than 1 in exact arithmetic, and the bounds are for the model as stored.
    """
    lower = np.maximum(found.lower, 0.0)
    return Bounds.around(np.clip(found.value, 0.0, 1.0), lower, found.upper)


def next_probs(P: CsrMatrix, target: BoolArray) -> Bounds:
    """Probability that the next state is in *target* (``X target``).

    :param P: row-stochastic CSR transition matrix.
    :param target: states to reach in one step.
    """
    value, lower, upper = certify.enclose_product(P, target.astype(np.float64))
    return _probabilities(Bounds(value, lower, upper))


def bounded_until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                        k: int, *, progress: Progress | None = None,
                        workspace: Workspace | None = None) -> Bounds:
    """Probability of reaching *target* within *k* steps while staying in *remain*.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :param k: step bound (``U<=k``), at least 0.
    :param progress: told ``(steps done, k, "steps")`` as the iteration goes.
    :param workspace: as for :func:`until_probs`; with one, the unbounded until may
        bound the steps of a bound too large to iterate (:func:`_ceiling`).
    """
    moving = _rows_in(P, remain & ~target)
    near = _within_steps(moving, target, k)
    if not near.any():
        return Bounds.exact(np.zeros(P.shape[0]))
    hit = target.astype(np.float64)
    index = np.flatnonzero(near)
    trend = Trend.up_to(lambda: _ceiling(P, remain, target, index, workspace))
    if near.all():
        return _probabilities(_step_power(moving, Bounds.exact(hit), hit, k, progress, trend))
    # States farther than k steps from the target have probability exactly 0, and
    # so has every such successor of a nearer state at each of the k iterations:
    # iterating on the near states alone gives the same values (Storm does the same).
    sub = sp.csr_matrix(moving[index][:, index])
    del moving
    found = _step_power(sub, Bounds.exact(hit[index]), hit[index], k, progress, trend)
    return _probabilities(_spread(np.zeros(P.shape[0]), near, found))


def _ceiling(P: CsrMatrix, remain: BoolArray, target: BoolArray, index: IntArray,
             workspace: Workspace | None) -> FloatArray | None:
    """An upper bound of ``remain U<=k target`` for every *k*, on the states *index*:
    the unbounded until's, when each row that moves sums to at most 1 exactly (None
    otherwise, or without a workspace). ``docs/numerics.md`` has the argument."""
    if workspace is None:
        return None
    moves = index[remain[index] & ~target[index]]
    if not bool(certify.sums_at_most_one(P[moves]).all()):
        return None
    return until_probs(P, remain, target, workspace=workspace).upper[index]


def _within_steps(moving: CsrMatrix, target: BoolArray, k: int) -> BoolArray:
    """States with a path of at most *k* steps of *moving* (rows of the states that
    may move) to *target*: a breadth-first search over the reversed graph cut at
    depth *k* (in C; any superset would do, so stored zeros may count as edges)."""
    n = moving.shape[0]
    if not target.any():
        return np.zeros(n, dtype=bool)
    # The transpose is a CSC view of the same arrays; csgraph makes one CSR copy.
    distance = csgraph.dijkstra(moving.T, directed=True, indices=np.flatnonzero(target),
                                unweighted=True, min_only=True, limit=min(k, n) + 0.5)
    return np.asarray(np.isfinite(distance), dtype=bool)


def lower_bounded_until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                              k: int, *, workspace: Workspace) -> Bounds:
    """Probability of ``remain U>=k target``: *remain* for the first *k* steps, then until.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that must hold before *target* is reached.
    :param target: states to reach, at step *k* or later.
    :param k: lower step bound, at least 0.
    :param workspace: as for :func:`until_probs`.
    """
    later = until_probs(P, remain, target, workspace=workspace)
    found = _step_power(_rows_in(P, remain), later, np.zeros(P.shape[0]), k, workspace.monitor)
    return _probabilities(found)


def interval_until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                         low: int, high: int, *, progress: Progress | None = None,
                         workspace: Workspace | None = None) -> Bounds:
    """Probability of ``remain U[low,high] target``: *remain* for the first *low* steps,
    then *target* within ``high - low`` more steps, passing through *remain*.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that must hold before *target* is reached.
    :param target: states to reach, at a step in ``[low, high]``.
    :param low: first step that counts, at least 0.
    :param high: last step that counts, at least *low*.
    :param progress: as for :func:`bounded_until_probs`, per part.
    :param workspace: as for :func:`bounded_until_probs`.
    """
    later = bounded_until_probs(P, remain, target, high - low, progress=progress,
                                workspace=workspace)
    found = _step_power(_rows_in(P, remain), later, np.zeros(P.shape[0]), low, progress)
    return _probabilities(found)


def cumulative_rewards(P: CsrMatrix, rewards: FloatArray, k: int, *,
                       progress: Progress | None = None) -> Bounds:
    """Expected reward of the first *k* steps (``C<=k``).

    :param P: row-stochastic CSR transition matrix.
    :param rewards: reward earned per step taken from each state (state + transition).
    :param k: number of steps, at least 0.
    :param progress: as for :func:`bounded_until_probs`.
    """
    offset = np.asarray(rewards, dtype=np.float64)
    trend = horizon.GAINING if bool(np.all(offset >= 0)) else horizon.RISING
    found = _step_power(P, Bounds.exact(np.zeros_like(offset)), offset, k, progress, trend)
    if np.all(offset >= 0):  # a sum of such rewards is never negative (nor one overflown)
        return Bounds(found.value, np.maximum(found.lower, 0.0), found.upper)
    return found


def instantaneous_rewards(P: CsrMatrix, state_rewards: FloatArray, k: int, *,
                          progress: Progress | None = None) -> Bounds:
    """Expected state reward of the state occupied at step *k* (``I=k``).

    :param P: row-stochastic CSR transition matrix.
    :param state_rewards: reward of being in each state.
    :param k: the step, at least 0.
    :param progress: as for :func:`bounded_until_probs`.
    """
    start = np.asarray(state_rewards, dtype=np.float64)
    found = _step_power(P, Bounds.exact(start), np.zeros_like(start), k, progress)
    # The value is a weighted sum of the states' rewards: so bounded however far the
    # bound (where the rounds' error radius grows past them).
    return found.within(*horizon.power_range(P, float(start.min(initial=0.0)),
                                             float(start.max(initial=0.0)), k))


def absorption(P: CsrMatrix, fixed: BoolArray, known: Bounds, *,
               workspace: Workspace) -> Bounds:
    """``x = P x`` off *fixed*, ``x = known`` on it: each state's expectation of the
    value of the *fixed* state where it is absorbed, with certified bounds.

    Every state outside *fixed* must reach *fixed* almost surely (the BSCCs, for
    long-run values), so the fixed point is unique; it is certified like
    :func:`until_probs`, with the known values as intervals.

    :param P: row-stochastic CSR transition matrix.
    :param fixed: the states whose values are known.
    :param known: the values (meaningful on *fixed* only), non-negative.
    :param workspace: as for :func:`until_probs`.
    """
    lower = np.where(fixed, known.lower, 0.0)
    upper = np.where(fixed, known.upper, 0.0)
    maybe = ~fixed & ~prob0(P, np.ones(P.shape[0], dtype=bool), fixed & (upper > 0),
                            workspace=workspace)
    if not maybe.any():
        return Bounds.around(np.where(fixed, known.value, 0.0), lower, upper)
    # x = P x holds on every state outside fixed (0 where no positive value is reachable).
    system = _system(P, maybe, ~fixed, workspace=workspace)
    F = system.affine(lower, upper, None)
    point = np.where(fixed, known.value, 0.0)
    found = _certified(F, system, point, None, (0.0, float(np.max(upper))))
    found = _restrict(found, system.unknowns, maybe)
    value, low, high = point.copy(), lower.copy(), upper.copy()
    value[maybe], low[maybe], high[maybe] = found.value, found.lower, found.upper
    return Bounds.around(value, low, high)
