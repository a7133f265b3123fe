"""Step-bounded operators: ``X``, ``U<=k``, ``U>=k``, ``U[a,b]``, ``C<=k``, ``I=k``.

Each is a finite-horizon Bellman recursion: ``k`` rounds of
``x_r(s) = opt_a (o_a + P_a x_{r-1})`` on the states that move, the others held
at fixed values. An optimal strategy for a finite horizon takes, at each step,
a choice that attains the optimum of that round (dynamic programming), so the
strategy returned is step-dependent (:class:`StepStrategy`).

A rigorous error radius is carried through the rounds, as on the DTMC side
(:func:`_round`: the rounding of each round enclosed by :func:`enclose_product`,
the inherited error pushed through the worst row). As there, these operators
read the stored entries as they are. A bound too large to iterate runs as
:mod:`~veribattery.checker.certify.horizon` says (``docs/mdp-numerics.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray, RankArray
from veribattery.checker.certify import (
    TERM_FLOOR,
    enclose_product,
    error_coefficient,
    horizon,
    row_terms,
    spectral_cap,
    step_up,
    step_up_in_place,
    sums_at_most_one,
)
from veribattery.checker.certify.bounds import Bounds, round_down, round_up
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.certify.horizon import Trend
from veribattery.checker.mdp.graph import within_steps
from veribattery.checker.mdp.levels import ChoiceLevels
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.plain_rounds import plain_rounds
from veribattery.checker.mdp.reach import reach_probability
from veribattery.checker.mdp.result import MdpResult
from veribattery.checker.mdp.strategy import StepStrategy, Strategy
from veribattery.checker.mdp.system import Objective

__all__ = [
    "bounded_reach_probability",
    "cumulative_reward",
    "instantaneous_reward",
    "interval_reach_probability",
    "later_reach_probability",
    "next_probability",
]


@dataclass(frozen=True, slots=True)
class _Rounds:
    """What the recursion needs besides the start: who moves, what the others hold,
    and what is known of the values of the rounds a large bound does not run."""

    moving: BoolArray
    fixed: Bounds
    offset: FloatArray | None
    objective: Objective
    trend: Trend = horizon.NONNEGATIVE

    def laid_out(self, levels: ChoiceLevels) -> _Rounds:
        """These rounds in the order of *levels*' states and rows."""
        fixed = Bounds(*(levels.states(v) for v in (self.fixed.value, self.fixed.lower,
                                                      self.fixed.upper)))
        offset = None if self.offset is None else levels.choices(self.offset)
        return _Rounds(levels.states(self.moving), fixed, offset, self.objective, self.trend)


def next_probability(mdp: MDP, target: BoolArray, *, objective: Objective) -> MdpResult:
    """Minimal or maximal probability that the next state is in *target* (``X target``)."""
    everywhere = np.ones(mdp.num_states, dtype=bool)
    start = Bounds.exact(target.astype(np.float64))
    return _iterated(mdp, start, _Rounds(everywhere, start, None, objective), 1, None)


def bounded_reach_probability(mdp: MDP, target: BoolArray, steps: int, *,
                              objective: Objective, remain: BoolArray | None = None,
                              progress: Progress | None = None) -> MdpResult:
    """Minimal or maximal probability of ``remain U<=steps target``.

    :param steps: the step bound, at least 0.
    :param remain: states that may be passed through before *target* (None: all).
    :param progress: told ``(rounds done, steps, "steps")`` as the rounds go.
    :return: values with certified bounds and a step-dependent optimal strategy.
    """
    remain = np.ones(mdp.num_states, dtype=bool) if remain is None else remain
    start = Bounds.exact(target.astype(np.float64))
    below = remain  # (the name the closure keeps: mypy would widen *remain* again)
    trend = Trend.up_to(lambda: _ceiling(mdp, target, below, objective))
    # (a state more than *steps* steps from the target is 0 exactly: kept out of the
    # rounds, not given a rounding radius -- `0 +- 2.5e-270`, and `P>0` on it taken to
    # exact arithmetic, 5 s on the mission MDP)
    moving = remain & ~target
    moving &= within_steps(mdp.transitions, mdp.choice_owner, moving, target, steps)
    rounds = _Rounds(moving, start, None, objective, trend)
    return _iterated(mdp, start, rounds, steps, None, progress)


def _ceiling(mdp: MDP, target: BoolArray, remain: BoolArray,
             objective: Objective) -> FloatArray | None:
    """An upper bound of the optimal ``remain U<=k target`` for every *k*: the unbounded
    optimum's, when each choice of a state that moves sums to at most 1 exactly (None
    otherwise). ``docs/mdp-numerics.md`` has the argument."""
    choices = np.flatnonzero((remain & ~target)[mdp.choice_owner])
    if not bool(sums_at_most_one(mdp.transitions[choices]).all()):
        return None
    found = reach_probability(mdp, target, objective=objective, remain=remain)
    return found.bounds.upper


def later_reach_probability(mdp: MDP, target: BoolArray, steps: int, *,
                            objective: Objective, remain: BoolArray | None = None,
                            progress: Progress | None = None) -> MdpResult:
    """Minimal or maximal probability of ``remain U>=steps target``: *remain* for the
    first *steps* steps, then ``remain U target`` (its strategy afterwards)."""
    remain = np.ones(mdp.num_states, dtype=bool) if remain is None else remain
    later = reach_probability(mdp, target, objective=objective, remain=remain,
                              progress=progress)
    assert isinstance(later.strategy, Strategy)
    return _iterated(mdp, later.bounds, _blocked(mdp, remain, objective), steps,
                     later.strategy, progress)


def interval_reach_probability(mdp: MDP, target: BoolArray, low: int, high: int, *,
                               objective: Objective, remain: BoolArray | None = None,
                               progress: Progress | None = None) -> MdpResult:
    """Minimal or maximal probability of ``remain U[low,high] target``: *remain* for the
    first *low* steps, then *target* within ``high - low`` more, through *remain*."""
    remain = np.ones(mdp.num_states, dtype=bool) if remain is None else remain
    window = bounded_reach_probability(mdp, target, high - low, objective=objective,
                                       remain=remain, progress=progress)
    return _iterated(mdp, window.bounds, _blocked(mdp, remain, objective), low,
                     window.strategy, progress)


def cumulative_reward(mdp: MDP, rewards: FloatArray, steps: int, *,
                      objective: Objective, progress: Progress | None = None) -> MdpResult:
    """Minimal or maximal expected reward of the first *steps* steps (``C<=steps``).

    :param rewards: per choice, the reward of one step taken with it (nonnegative).
    """
    everywhere = np.ones(mdp.num_states, dtype=bool)
    start = Bounds.exact(np.zeros(mdp.num_states))
    offset = np.asarray(rewards, dtype=np.float64)
    rounds = _Rounds(everywhere, start, offset, objective, horizon.GAINING)
    return _iterated(mdp, start, rounds, steps, None, progress)


def instantaneous_reward(mdp: MDP, state_rewards: FloatArray, steps: int, *,
                         objective: Objective, progress: Progress | None = None
                         ) -> MdpResult:
    """Minimal or maximal expected reward of the state occupied at step *steps* (``I=k``).

    :param state_rewards: per state, its reward (nonnegative).
    """
    everywhere = np.ones(mdp.num_states, dtype=bool)
    rewards = np.asarray(state_rewards, dtype=np.float64)
    start = Bounds.exact(rewards)
    found = _iterated(mdp, start, _Rounds(everywhere, start, None, objective), steps, None,
                      progress)
    # (under any strategy a weighted sum of the states' rewards: so bounded)
    reach = horizon.power_range(mdp.transitions, float(rewards.min(initial=0.0)),
                                float(rewards.max(initial=0.0)), steps)
    return MdpResult(found.bounds.within(*reach), found.strategy)


def _blocked(mdp: MDP, remain: BoolArray, objective: Objective) -> _Rounds:
    """Rounds in which the states outside *remain* fail (value 0)."""
    return _Rounds(remain, Bounds.exact(np.zeros(mdp.num_states)), None, objective)


def _iterated(mdp: MDP, start: Bounds, rounds: _Rounds, steps: int,
              then: Strategy | StepStrategy | None,
              progress: Progress | None = None) -> MdpResult:
    """*steps* rounds from *start*; the strategy of the last round is taken first.

    From an exact start, the rounds run in plain floating point where their a priori
    bounds are tight enough (:mod:`~veribattery.checker.mdp.plain_rounds`); else each
    carries an error radius. A bound beyond :data:`horizon.ROUND_LIMIT` runs at most
    :func:`horizon.rounds` rounds (:func:`_beyond`); the rounds not run take the last
    round's choices.
    """
    levels = ChoiceLevels.of(mdp)
    rounds = rounds.laid_out(levels)
    value, radius = levels.states(start.value), levels.states(_radius(start))
    fixed_radius = _radius(rounds.fixed)
    # (one round keeps the per-row enclosure: from 0s and 1s it is exact where a row reads
    # one 1, as X's and U<=1's results are)
    if 1 < steps <= horizon.ROUND_LIMIT and not (radius.any() or fixed_radius.any()):
        decisions = _Decisions(levels)
        plain = plain_rounds(levels, value, rounds.fixed.value, rounds.moving, rounds.offset,
                             rounds.objective, steps, decisions.add, progress)
        if plain is not None:
            restored = Bounds(*(levels.restored(v) for v in (plain.value, plain.lower,
                                                             plain.upper)))
            return MdpResult(restored, decisions.strategy(mdp, steps, then))
    rows = _Rows.of(levels)
    decisions = _Decisions(levels)
    budget = horizon.rounds(steps, mdp.transitions.nnz)
    best: Bounds | None = None  # the last check's bounds, while only the radius moves
    for done in range(1, budget + 1):
        following, grown, rank = _round(levels, rounds, value, radius, fixed_radius, rows)
        decisions.add(rank)
        steady = np.array_equal(following, value)
        if steady and np.array_equal(grown, radius):
            break  # every later round is this one
        if rounds.trend.gaining and horizon.gain_checkpoint(done, steps):
            carried = _gained(mdp, levels, rows, rounds, (value, radius), following,
                              steps - done + 1)
            if carried is not None and bool(carried.precise_states().all()):
                return MdpResult(carried, decisions.strategy(mdp, steps, then))
        if horizon.checkpoint(done, steps) or done == budget < steps:
            found = _beyond(mdp, rounds.trend, (levels.restored(value), levels.restored(radius)),
                            (levels.restored(following), levels.restored(grown)),
                            steps - done + 1)
            if best is not None and steady and not _narrower(found, best):
                found = best  # only the radius moves, and it no longer narrows
            if found is best or done == budget or bool(found.precise_states().all()):
                return MdpResult(found, decisions.strategy(mdp, steps, then))
            best = found if steady else None
        value, radius = following, grown
        if progress is not None:
            progress(done, steps, "steps")
    value, radius = levels.restored(value), levels.restored(radius)
    with np.errstate(invalid="ignore"):  # (a radius of 0: the value is exact)
        upper = np.where(radius == 0, value, round_up(value + radius))
    upper = np.where(np.isnan(upper), np.inf, upper)  # (inf - inf: beyond the doubles)
    found = Bounds(value, _lower(value, radius), upper)
    if steps > horizon.ROUND_LIMIT and rounds.trend.ceiling is not None and bool(
            np.any(upper > 1.0)):
        # (settled before a bound beyond the rounds run, whose checkpoints would have
        # capped it: a probability's radius past 1 is capped by the ceiling, if any)
        found = horizon.meet(found, value, found.lower, rounds.trend)
    return MdpResult(found, decisions.strategy(mdp, steps, then))


def _gained(mdp: MDP, levels: ChoiceLevels, rows: _Rows, rounds: _Rounds,
            start: tuple[FloatArray, FloatArray], following: FloatArray,
            remaining: int) -> Bounds | None:
    """:func:`horizon.gained` of the *remaining* rounds from *start* (in *levels*' order),
    whose round gave *following*: that round's rounding is its rows' again, the most
    of each state's."""
    value, radius = start
    _, rounding = rows.enclosed(value, rounds.offset)
    delta = levels.optimum(rounding, np.maximum)
    return horizon.gained((levels.restored(value), levels.restored(radius)),
                          (levels.restored(following), levels.restored(delta)), remaining,
                          horizon.row_sum_bounds(mdp.transitions))


def _beyond(mdp: MDP, trend: Trend, before: tuple[FloatArray, FloatArray],
            after: tuple[FloatArray, FloatArray], remaining: int) -> Bounds:
    """Bounds of the value *remaining* rounds after *before* (value, radius), whose
    next round gave *after*.

    If the round left the values as they were, only the radius moves in the rounds
    left (:func:`horizon.drifted`), narrowed by the trend; else what the trend knows
    (:func:`horizon.beyond`).
    """
    (value, radius), (following, grown) = before, after
    lower = _lower(value, radius)
    if not np.array_equal(following, value):
        return horizon.beyond(value, lower, trend)
    rho = max(1.0, spectral_cap(mdp.transitions))
    drift = horizon.drifted(radius, grown, rho, remaining)
    with np.errstate(invalid="ignore"):
        found = Bounds(value, _lower(value, drift), round_up(value + drift))
    return horizon.meet(found, value, lower, trend)


def _narrower(found: Bounds, than: Bounds) -> bool:
    """Whether the widest interval of *found* is narrower than that of *than*."""
    return bool(np.max(found.width) < np.max(than.width))


def _lower(value: FloatArray, radius: FloatArray) -> FloatArray:
    """The certified lower bound of nonnegative values with their radius (a radius of 0:
    the value is exact; an infinite value with an infinite radius, of a value beyond the
    doubles, is bounded by 0 below: fmax drops the NaN of inf - inf)."""
    with np.errstate(invalid="ignore"):
        return np.where(radius == 0, value, np.fmax(round_down(value - radius), 0.0))


def _up(total: FloatArray) -> FloatArray:
    """An upper bound of a nonnegative sum or difference computed as *total* (exact if
    0: a float sum or difference is 0 only when it is exactly 0)."""
    return np.where(total == 0, 0.0, step_up(total))


def _radius(bounds: Bounds) -> FloatArray:
    """A bound of ``|value - exact|`` per state."""
    with np.errstate(invalid="ignore"):
        below, above = bounds.value - bounds.lower, bounds.upper - bounds.value
        gap = np.maximum(_up(below), _up(above))
    return np.asarray(np.where(np.isnan(gap), 0.0, gap), dtype=np.float64)


@dataclass(frozen=True, slots=True)
class _Rows:
    """Per row of the choice matrix, the constants of the rounding bound of one product
    ``P_a x + o_a`` with nonnegative terms (:func:`enclosed`): Higham's ``gamma_k`` for
    its stored entries plus the offset, and the underflow of each product (counted as
    ``TERM_FLOOR``, a normal number, as :class:`certify.AffineMap` does)."""

    matrix: CsrMatrix
    terms: FloatArray
    coefficient: FloatArray
    underflow: FloatArray

    @classmethod
    def of(cls, levels: ChoiceLevels) -> _Rows:
        terms = row_terms(levels.matrix)
        counted = terms + 1.0
        return cls(levels.matrix, terms, error_coefficient(counted), counted * TERM_FLOOR)

    def enclosed(self, x: FloatArray, offset: FloatArray | None) -> tuple[FloatArray, FloatArray]:
        """``y = fl(P x + o)`` and a bound of ``|y - (P x + o)|`` per row (*x*, *o* >= 0).

        The terms are nonnegative, so the magnitude in the bound is *y* itself;
        vectors of 0s and 1s without an offset go through :func:`enclose_product`,
        whose products are exact (so exact results stay exact).
        """
        if not x.any() and (offset is None or not offset.any()):
            zeros = np.zeros(self.matrix.shape[0])
            return zeros, zeros.copy()  # (an exact radius of 0 stays 0)
        if offset is None and bool(np.all((x == 0) | (x == 1))):
            y, low, high = enclose_product(self.matrix, x, None, self.terms)
            return y, _up(np.maximum(high - y, y - low))
        y = np.asarray(self.matrix @ x, dtype=np.float64)
        if offset is not None:
            with np.errstate(over="ignore"):  # beyond the doubles: inf, and so its radius
                y += offset
        error = self.coefficient * y
        error += self.underflow
        step_up_in_place(error)
        return y, error


def _round(levels: ChoiceLevels, rounds: _Rounds, value: FloatArray, radius: FloatArray,
           fixed_radius: FloatArray, rows: _Rows
           ) -> tuple[FloatArray, FloatArray, RankArray]:
    """One Bellman round, in *levels*' order: the point values, their error radius, the
    choices taken (each state's rank among its choices).

    ``|opt_a y_a - opt_a f_a(x*)| <= max_a |y_a - f_a(x*)| <= max_a (err_a + P_a r)``
    for the float images ``y_a`` of the point values (rounding ``err_a``, enclosed)
    and their radius ``r``, whichever optimum is taken: two products per round.
    """
    reduce = np.maximum if rounds.objective == "max" else np.minimum
    images, rounding = rows.enclosed(value, rounds.offset)
    spread, error = rows.enclosed(radius, rounding)
    spread += error
    # _up is monotone, so rounding each state's widest choice up is rounding every
    # choice up, then taking the widest (and a third of the work). 0 only where both
    # terms are: an exact value stays exact.
    grown = _up(levels.optimum(spread, np.maximum))
    best = levels.optimum(images, reduce)
    moving, fixed = rounds.moving, rounds.fixed
    return (np.where(moving, best, fixed.value),
            np.where(moving, grown, fixed_radius),
            np.where(moving, levels.first_attaining(images, best), 0))


class _Decisions:
    """The choices of rounds 1, 2, ... (round r: r steps to go), kept as a
    :class:`StepStrategy` keeps them: the first, then what each round changes (as ranks
    in *levels*' order while the rounds run)."""

    __slots__ = ("_changes", "_first", "_last", "_levels")

    def __init__(self, levels: ChoiceLevels) -> None:
        self._levels = levels
        self._first: RankArray | None = None
        self._last: RankArray | None = None
        self._changes: list[tuple[IntArray, RankArray]] = []

    def add(self, rank: RankArray) -> None:
        """The choices of the next round, as ranks in *levels*' order."""
        if self._last is None:
            self._first = rank
        else:
            differ = np.flatnonzero(self._last != rank)
            self._changes.append(_NO_CHANGE if not differ.size else (differ, rank[differ]))
        self._last = rank

    def strategy(self, mdp: MDP, steps: int, then: Strategy | StepStrategy | None
                 ) -> StepStrategy:
        """The strategy for *steps* steps: the rounds not run repeat the last one."""
        if self._first is None:
            return StepStrategy(0, mdp.row_groups[:-1].copy(), (), then)
        changes = tuple(change if change is _NO_CHANGE else self._chosen(*change)
                        for change in self._changes)
        return StepStrategy(steps, self._levels.chosen(self._first), changes, then)

    def _chosen(self, positions: IntArray, ranks: RankArray) -> tuple[IntArray, IntArray]:
        """The states at *positions* of the layout and their choices of *ranks*."""
        states = self._levels.order[positions]
        return states, self._levels.groups[states] + ranks


#: A round that changes no choice (one shared object: a bound of 10^6 rounds keeps
#: 10^6 references, not 10^6 pairs of arrays).
_NO_CHANGE: tuple[IntArray, IntArray] = (np.zeros(0, dtype=np.int64),
                                         np.zeros(0, dtype=np.int64))
