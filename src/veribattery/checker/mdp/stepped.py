"""Step-bounded operators: ``X``, ``U<=k``, ``U>=k``, ``U[a,b]``, ``C<=k``, ``I=k``.

Each is a finite-horizon Bellman recursion: ``k`` rounds of
``x_r(s) = opt_a (o_a + P_a x_{r-1})`` on the states that move, the others held
at fixed values. An optimal strategy for a finite horizon takes, at each step,
a choice that attains the optimum of that round (dynamic programming), so the
strategy returned is step-dependent (:class:`StepStrategy`).

The bounds are carried through the rounds: with ``lo_{r-1} <= x*_{r-1} <=
hi_{r-1}``, monotonicity gives ``opt_a (o_a + P_a lo) <= x*_r``, and a rigorous
lower enclosure of each row's product (:func:`enclose_product`) keeps that
true in floating point; likewise above. As on the DTMC side, these operators
read the stored entries as they are.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.bounds import Bounds
from veribattery.checker.certify import enclose_product, row_terms
from veribattery.checker.mdp.model import MDP
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
    """What the recursion needs besides the start: who moves, what the others hold."""

    moving: BoolArray
    fixed: Bounds
    offset: FloatArray | None
    objective: Objective


def next_probability(mdp: MDP, target: BoolArray, *, objective: Objective) -> MdpResult:
    """Minimal or maximal probability that the next state is in *target* (``X target``)."""
    everywhere = np.ones(mdp.num_states, dtype=bool)
    start = Bounds.exact(target.astype(np.float64))
    return _iterated(mdp, start, _Rounds(everywhere, start, None, objective), 1, None)


def bounded_reach_probability(mdp: MDP, target: BoolArray, steps: int, *,
                              objective: Objective,
                              remain: BoolArray | None = None) -> MdpResult:
    """Minimal or maximal probability of ``remain U<=steps target``.

    :param steps: the step bound, at least 0.
    :param remain: states that may be passed through before *target* (None: all).
    :return: values with certified bounds and a step-dependent optimal strategy.
    """
    remain = np.ones(mdp.num_states, dtype=bool) if remain is None else remain
    start = Bounds.exact(target.astype(np.float64))
    rounds = _Rounds(remain & ~target, start, None, objective)
    return _iterated(mdp, start, rounds, steps, None)


def later_reach_probability(mdp: MDP, target: BoolArray, steps: int, *,
                            objective: Objective,
                            remain: BoolArray | None = None) -> MdpResult:
    """Minimal or maximal probability of ``remain U>=steps target``: *remain* for the
    first *steps* steps, then ``remain U target`` (its strategy afterwards)."""
    remain = np.ones(mdp.num_states, dtype=bool) if remain is None else remain
    later = reach_probability(mdp, target, objective=objective, remain=remain)
    assert isinstance(later.strategy, Strategy)
    return _iterated(mdp, later.bounds, _blocked(mdp, remain, objective), steps,
                     later.strategy)


def interval_reach_probability(mdp: MDP, target: BoolArray, low: int, high: int, *,
                               objective: Objective,
                               remain: BoolArray | None = None) -> MdpResult:
    """Minimal or maximal probability of ``remain U[low,high] target``: *remain* for the
    first *low* steps, then *target* within ``high - low`` more, through *remain*."""
    remain = np.ones(mdp.num_states, dtype=bool) if remain is None else remain
    window = bounded_reach_probability(mdp, target, high - low, objective=objective,
                                       remain=remain)
    return _iterated(mdp, window.bounds, _blocked(mdp, remain, objective), low,
                     window.strategy)


def cumulative_reward(mdp: MDP, rewards: FloatArray, steps: int, *,
                      objective: Objective) -> MdpResult:
    """Minimal or maximal expected reward of the first *steps* steps (``C<=steps``).

    :param rewards: per choice, the reward of one step taken with it (nonnegative).
    """
    everywhere = np.ones(mdp.num_states, dtype=bool)
    start = Bounds.exact(np.zeros(mdp.num_states))
    offset = np.asarray(rewards, dtype=np.float64)
    return _iterated(mdp, start, _Rounds(everywhere, start, offset, objective), steps, None)


def instantaneous_reward(mdp: MDP, state_rewards: FloatArray, steps: int, *,
                         objective: Objective) -> MdpResult:
    """Minimal or maximal expected reward of the state occupied at step *steps* (``I=k``).

    :param state_rewards: per state, its reward (nonnegative).
    """
    everywhere = np.ones(mdp.num_states, dtype=bool)
    start = Bounds.exact(np.asarray(state_rewards, dtype=np.float64))
    return _iterated(mdp, start, _Rounds(everywhere, start, None, objective), steps, None)


def _blocked(mdp: MDP, remain: BoolArray, objective: Objective) -> _Rounds:
    """Rounds in which the states outside *remain* fail (value 0)."""
    return _Rounds(remain, Bounds.exact(np.zeros(mdp.num_states)), None, objective)


def _iterated(mdp: MDP, start: Bounds, rounds: _Rounds, steps: int,
              then: Strategy | StepStrategy | None) -> MdpResult:
    """*steps* rounds from *start*; the strategy of the last round is taken first."""
    value, lower, upper = start.value, start.lower, start.upper
    terms = row_terms(mdp.transitions)
    decisions: list[IntArray] = []
    for _ in range(steps):
        following = _round(mdp, rounds, value, lower, upper, terms)
        decisions.append(following[3])
        if all(np.array_equal(a, b) for a, b in zip(following[:3], (value, lower, upper),
                                                     strict=True)):
            decisions += [following[3]] * (steps - len(decisions))
            break
        value, lower, upper = following[:3]
    strategy = _compact(mdp, decisions, then)
    return MdpResult(Bounds.around(value, lower, upper), strategy)


def _round(mdp: MDP, rounds: _Rounds, value: FloatArray, lower: FloatArray,
           upper: FloatArray, terms: FloatArray
           ) -> tuple[FloatArray, FloatArray, FloatArray, IntArray]:
    """One Bellman round: the point values, both bounds and the choices attaining them."""
    reduce = np.maximum if rounds.objective == "max" else np.minimum
    starts = mdp.row_groups[:-1]
    images = mdp.transitions @ value
    if rounds.offset is not None:
        images = images + rounds.offset
    low = enclose_product(mdp.transitions, lower, rounds.offset, terms)[1]
    high = enclose_product(mdp.transitions, upper, rounds.offset, terms)[2]
    best = reduce.reduceat(images, starts)
    choice = _first_best(mdp, images, best)
    moving = rounds.moving
    fixed = rounds.fixed
    return (np.where(moving, best, fixed.value),
            np.where(moving, np.maximum(reduce.reduceat(low, starts), 0.0), fixed.lower),
            np.where(moving, reduce.reduceat(high, starts), fixed.upper),
            np.where(moving, choice, starts))


def _first_best(mdp: MDP, images: FloatArray, best: FloatArray) -> IntArray:
    """Per state, its first choice whose image equals *best*."""
    hits = images == best[mdp.choice_owner]
    rows = np.where(hits, np.arange(images.size), images.size)
    return np.asarray(np.minimum.reduceat(rows, mdp.row_groups[:-1]), dtype=np.int64)


def _compact(mdp: MDP, decisions: list[IntArray],
             then: Strategy | StepStrategy | None) -> StepStrategy:
    """The decisions of rounds 1..k (round r: r steps to go) as a :class:`StepStrategy`."""
    if not decisions:
        return StepStrategy(0, mdp.row_groups[:-1].copy(), (), then)
    changes = []
    for before, now in itertools.pairwise(decisions):
        differ = np.flatnonzero(before != now)
        changes.append((differ, now[differ]))
    return StepStrategy(len(decisions), decisions[0], tuple(changes), then)
