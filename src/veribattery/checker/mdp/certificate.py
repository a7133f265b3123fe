"""Certified bounds of the optimal values of a :class:`ChoiceSystem`.

After the pre-pass of each operator the Bellman operator ``B`` of the system has
exactly one fixed point, the optimal value ``x*`` (``docs/mdp-numerics.md``
says why, operator by operator), and ``B`` is monotone. Then, as on the DTMC
side (``docs/numerics.md``):

* a vector *u* with ``B(u) <= u`` is an upper bound of ``x*``, one with
  ``B(l) >= l`` a lower bound (``B^n(u)`` decreases to the unique fixed point);
* from a certified pair, ``max(l, B(l))`` and ``min(u, B(u))`` stay certified
  (interval iteration, Haddad & Monmege 2018; Baier et al., CAV 2017).

The tests use rigorous enclosures of ``B`` (:meth:`ChoiceSystem.bound_images`):
the maximum (minimum) of upper bounds of the rows' images is an upper bound of
the maximum (minimum) of the exact images, and likewise below. Candidates come
from policy iteration's approximation *x*: ``x +- (c d + slack)`` for a margin
*d* (:func:`_margin`) and growing *c*, moved outward where a state fails
(:func:`_pushed`); failing all, the states that fail are set to the trivial
bound and the test is repeated; then interval iteration tightens what is left.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.checker.certify import ETA, UNIT_ROUNDOFF, step_down, step_up
from veribattery.checker.certify.bounds import Bounds, current_precision
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.mdp.image import BellmanImage
from veribattery.checker.mdp.solve import Evaluation, evaluate, improvements, switched
from veribattery.checker.mdp.system import ChoiceSystem, Objective
from veribattery.checker.mdp.topological import (
    class_levels,
    greedy_rows,
    rows_after_sweeps,
    topological_values,
)

__all__ = ["certified_values"]

#: Interval-iteration sweeps tried when the first certificate is not precise.
INTERVAL_SWEEPS = 2_000
#: ... unless the sweeps would cost more than this many nonzero visits in total.
INTERVAL_WORK = 400_000_000
#: Share of the largest defect given to every state before the margin is solved for.
SPREAD = 2.0**-20
#: Rounds of moving failing states outward before a factor is given up ...
PUSH_ROUNDS = 32
#: ... or after this many rounds, if more than this share of the states still fails: the
#: margin misses something systematic (rows tied with the strategy's), which a round of
#: pushing mends only one step back. On zeroconf (N=20, K=4) 5-40% of the states kept
#: failing for all 32 rounds (1-2 s of the check); where pushing succeeds, on the QComp
#: MDPs and the mission MDP, at most 2.6% fail in a round and 0.1% from the fifth on.
PUSH_PATIENCE = 4
GIVE_UP_SHARE = 0.02
#: Margin factors tried in turn.
FACTORS = (2.0, 16.0, 1024.0)
#: Rounds of resetting failed states to the trivial bound before a factor is given up.
REPAIR_ROUNDS = 4
#: Rows whose image of the approximation is this close to the best, relative, count as
#: tied with it (:class:`_TiedMargin`) ...
TIE = 2.0**-30
#: ... or this many times the state's spread defect.
TIE_SPREADS = 1024.0
#: Policy-iteration rounds for the tied rows' margin, tried in turn while no candidate
#: passes: a margin short of their optimum is still a candidate (the test decides, and
#: pushing mends small shortfalls), but on deep models pushing cannot mend it (a round
#: moves a shortfall one step back): the mission MDP of Fig. 6's basic batteries at
#: 6-11 Ah needs 5-10 rounds, and with 2 alone its upper bound fell to the trivial 1.
#: Two suffice on the paper's baseline, where twenty cost 3 s more for the same bounds.
TIED_ROUNDS = (2, 20)
#: Rounds after the sweeps' restart that still move before the tied problem is solved level
#: by level instead: on resource-gathering (B=1300, ``Tmin``), policy iteration moved a
#: little in each of 20 rounds (16 s), where one levelled pass settles it; on zeroconf the
#: sweeps' strategy settles at once, and the levelled pass would cost more than it.
LEVELLED_AFTER = 2

#: A larger factor's bound this close to *x*, as a share of the precision asked for, is
#: kept without seeking the tied rows' margin (policy iteration on the tied rows: 0.2-0.7
#: s on wlan and firewire, for bounds some 10^-12 tighter, relative, than the 10^-9 asked).
NEAR_ENOUGH = 1.0 / 64.0

Image = Callable[[FloatArray], FloatArray]


@dataclass(frozen=True, slots=True)
class _Images:
    """The rigorous images of the Bellman operator and the trivial bounds."""

    lower: Image
    upper: Image
    floor: FloatArray
    top: FloatArray


def certified_values(system: ChoiceSystem, objective: Objective, known: FloatArray,
                     offset: FloatArray | None, approximation: Evaluation | None,
                     ceiling: float, *, progress: Progress | None = None) -> Bounds:
    """Certified bounds of the unique fixed point of the system's Bellman operator.

    :param known: the exact values of ``system.known_states`` (nonnegative).
    :param offset: the reward of each row (nonnegative), or None.
    :param approximation: policy iteration's result, or None.
    :param ceiling: a trivial upper bound that passes the test by itself
        (1 for probabilities, ``inf`` for rewards); 0 is the trivial lower bound.
    :param progress: told ``(sweeps done, most sweeps, "sweeps")`` while interval
        iteration tightens the bounds.
    """

    images = _Images(*BellmanImage.pair(system, known, offset, objective),
                     np.zeros(system.size), np.full(system.size, ceiling))
    x, lower, upper = images.floor, images.floor, images.top
    if approximation is not None:
        x = np.clip(approximation.values, 0.0, ceiling)
        spread = _spread(x, images)
        margins = () if spread is None else _margins(spread, approximation)
        approximation = replace(approximation, untied=None)  # (its solver dies here)
        if spread is not None and margins:
            wider = _TiedMargin(system, objective, known, offset, x, spread, approximation)
            # (the tied rows' margin holds it only until its start is evaluated: its solver
            # then dies once the rounds move on, not kept beside theirs)
            del approximation
            lower, upper = _candidates(x, margins, images, wider,
                                       every_row_up=objective == "max")
    if not Bounds.around(x, lower, upper).precise_states().all():
        lower, upper = _tightened(system, images, x, lower, upper, progress)
    return Bounds.around(x, lower, upper)


def _spread(x: FloatArray, images: _Images) -> FloatArray | None:
    """The enclosed defect ``d0 = |B(x) - x|`` spread a little to every state (so that a
    margin made from it is a strict super-solution and the solver's noise cannot break
    it), or None where it is not finite."""
    with np.errstate(invalid="ignore", over="ignore"):
        defect = np.maximum(np.maximum(images.upper(x) - x, x - images.lower(x)), 0.0)
        defect = _above(defect)
    if not np.all(np.isfinite(defect)):
        return None
    return defect + (SPREAD * float(np.max(defect, initial=0.0))
                     + 4.0 * UNIT_ROUNDOFF * np.abs(x))


def _margins(spread: FloatArray, approximation: Evaluation) -> tuple[FloatArray, ...]:
    """The margins of the final strategy and of the one before ties were tightened (if
    any), those that are finite, the final one's first."""
    found = (_margin(spread, approximation),
             None if approximation.untied is None else _margin(spread, approximation.untied))
    return tuple(margin for margin in found if margin is not None)


def _margin(spread: FloatArray, approximation: Evaluation) -> FloatArray | None:
    """The margin ``d`` around *x*, or None: the *spread* defect pushed through the
    final strategy's system, ``d = (I - B_sigma)^-1 d0'``."""
    margin = approximation.correct(spread)
    if not np.all(np.isfinite(margin)):
        return None
    return np.maximum(margin, spread)  # (also drops the solver's negative noise)


class _TiedMargin:
    """A margin that also covers the rows tied with the optimum, after a number of
    rounds of policy iteration: called with more rounds, it goes on from the rounds
    already done.

    The side of the test that reads every row (the upper side of a maximum, the lower
    of a minimum) fails where a row ties with the strategy's but spreads its mass
    differently: ``P_b d`` can exceed ``d``. Here ``d`` is the largest expected sum of
    *spread* over the tied rows, ``d = max_b (s_b spread + P'_b d) / s_b`` -- a maximal
    reward problem on them (:class:`_TiedProblem`), approximated by a few rounds of
    policy iteration from the final strategy -- so that ``P_b d / s_b <= d - spread`` for
    every tied row. The rows further from the optimum than :data:`TIE` keep their
    distance. Called again for more rounds (the first ones' candidates failed), it first
    sweeps the values towards the maximum and goes on from their greedy strategy where
    that is no worse (:meth:`_TiedProblem.swept`): on the tied rows of zeroconf (K=4),
    policy iteration alone moved one switch a round, twenty rounds of an evaluation each.
    """

    def __init__(self, system: ChoiceSystem, objective: Objective, known: FloatArray,
                 offset: FloatArray | None, x: FloatArray, spread: FloatArray,
                 approximation: Evaluation) -> None:
        self._spread = spread
        # (lazy: nothing is evaluated before the first call)
        self._setup: Callable[[], tuple[_TiedProblem, Evaluation] | None] | None = partial(
            _tied_problem, system, objective, known, offset, x, spread, approximation)
        self._problem: _TiedProblem | None = None
        self._found: Evaluation | None = None
        self._steps: Iterator[Evaluation] = iter(())
        self._done = -1  # rounds done; -1: not even the start evaluated
        self._stopped = False
        self._swept = False
        self._since_sweeps: int | None = None  # rounds since the sweeps' restart

    def __call__(self, rounds: int) -> FloatArray | None:
        """The margin after *rounds* rounds in all, or None: none found, or the same as
        the last call's (the caller asks again only when that one's candidates failed)."""
        moved = self._restarted()
        while not self._stopped and self._done < rounds:
            if self._since_sweeps == LEVELLED_AFTER:
                self._since_sweeps = None
                if self._levelled():
                    moved = True
                    continue
            following = next(self._steps, None)
            if following is None:
                self._stopped = True
            else:
                self._found, self._done, moved = following, self._done + 1, True
                if self._since_sweeps is not None:
                    self._since_sweeps += 1
        if not moved or self._found is None or not np.all(np.isfinite(self._found.values)):
            return None
        return np.maximum(self._found.values, self._spread)

    def _restarted(self) -> bool:
        """Whether a new strategy starts the rounds: on the first call the final one,
        on the second the greedy one of the swept values (where no worse)."""
        if self._done < 0:
            assert self._setup is not None
            made = self._setup()
            self._setup = None  # (with it the approximation it holds)
            self._done = 0
            if made is None:
                self._stopped = True
                return False
            self._problem, self._found = made
        elif self._swept or self._problem is None or self._found is None:
            return False
        else:
            self._swept = True
            swept = self._problem.swept(self._found)
            if swept is None:
                return False
            self._found, self._done, self._stopped = swept, self._done + 1, False
            self._since_sweeps = 0
        self._steps = self._problem.rounds(self._found)
        return True

    def _levelled(self) -> bool:
        """Whether the greedy strategy of the tied problem's values solved level by level
        (:meth:`_TiedProblem.levelled`) restarts the rounds."""
        assert self._problem is not None and self._found is not None
        levelled = self._problem.levelled(self._found)
        if levelled is None:
            return False
        self._found, self._done = levelled, self._done + 1
        self._steps = self._problem.rounds(self._found)
        return True


@dataclass(frozen=True, slots=True)
class _TiedProblem:
    """The maximal expected sum of *reward* over the rows *system* keeps (the tied ones)."""

    system: ChoiceSystem
    reward: FloatArray

    @property
    def zeros(self) -> FloatArray:
        return np.zeros(self.system.known_states.size)

    def rounds(self, start: Evaluation) -> Iterator[Evaluation]:
        """The strategies of policy iteration's rounds from *start*."""
        return improvements(self.system, "max", self.zeros, self.reward, start)

    def swept(self, current: Evaluation) -> Evaluation | None:
        """The greedy strategy of *current*'s values swept towards the maximum
        (:func:`~veribattery.checker.mdp.topological.rows_after_sweeps`), evaluated, or
        None where it is *current*'s own or worse somewhere."""
        greedy = rows_after_sweeps(self.system, self.zeros, self.reward, current)
        return self._switched(current, greedy)

    def levelled(self, current: Evaluation) -> Evaluation | None:
        """The greedy strategy (ties kept on *current*'s rows) of the values solved level
        by level (:func:`~veribattery.checker.mdp.topological.topological_values`),
        evaluated, or None where that does not apply or is no better."""
        levels = class_levels(self.system)
        if not levels.within_limit:
            return None
        values = topological_values(self.system, "max", self.zeros, self.reward, current.rows,
                                    levels)
        images = self.system.images(values, self.zeros, self.reward)
        return self._switched(current, greedy_rows(images, self.system.groups[:-1], "max",
                                                   current.rows))

    def _switched(self, current: Evaluation, rows: IntArray) -> Evaluation | None:
        if np.array_equal(rows, current.rows):
            return None
        return switched(self.system, "max", self.zeros, self.reward, current, rows)


def _tied_problem(system: ChoiceSystem, objective: Objective, known: FloatArray,
                  offset: FloatArray | None, x: FloatArray, spread: FloatArray,
                  approximation: Evaluation) -> tuple[_TiedProblem, Evaluation] | None:
    """The maximal reward problem of the tied rows (:class:`_TiedMargin`) and the final
    strategy evaluated on it, or None where that fails."""
    rows = system.images(x, known, offset)
    best = system.best(rows, objective)[system.row_class]
    tolerance = TIE * np.abs(best) + TIE_SPREADS * spread[system.row_class]
    with np.errstate(invalid="ignore"):
        tied = (rows >= best - tolerance) if objective == "max" else (rows <= best + tolerance)
    tied[approximation.rows] = True
    try:
        sub = system.restricted(tied)
    except ValueError:
        return None
    start = (np.cumsum(tied) - 1)[approximation.rows]
    problem = _TiedProblem(sub, np.asarray(system.leave[tied] * spread[sub.row_class],
                                           dtype=np.float64))
    # Its start evaluated with the approximation's solver: the same rows of the same
    # entries.
    first = evaluate(sub, start, problem.zeros, problem.reward, approximation.solver)
    return None if first is None else (problem, first)


def _candidates(x: FloatArray, margins: tuple[FloatArray, ...], images: _Images,
                wider: Callable[[int], FloatArray | None], *, every_row_up: bool
                ) -> tuple[FloatArray, FloatArray]:
    """Certified bounds around *x*: for growing factors *c*, ``x +- (c d + slack)``,
    pushed where it fails (:func:`_pushed`), *d* the first of *margins* (at factor 2 the
    others too, in turn, where it fails); where factor 2 fails on the side that reads
    every row (above for a maximum: *every_row_up*), also the same with the margin of
    the tied rows (*wider*, :class:`_TiedMargin`, with more rounds while none passes;
    not sought when a larger factor passes :func:`_near_enough`), the tightest of those
    that pass; failing all, the last factor with the states that fail set to the
    trivial bounds."""
    return (_side(images.lower, x, margins, images, None if every_row_up else wider, up=False),
            _side(images.upper, x, margins, images, wider if every_row_up else None, up=True))


def _side(image: Image, x: FloatArray, margins: tuple[FloatArray, ...], images: _Images,
          wider: Callable[[int], FloatArray | None] | None, *, up: bool) -> FloatArray:
    trivial = images.top if up else images.floor
    for each in margins:
        first = _pushed(image, _around(x, each, FACTORS[0], images, up=up), trivial, up=up)
        if first is not None:
            return first
    margin = margins[0]
    found = [_first_passing(image, x, margin, FACTORS[1:], images, up=up)]
    if wider is not None and not (found[0] is not None and _near_enough(found[0], x, up=up)):
        for rounds in TIED_ROUNDS:
            tied = wider(rounds)
            if tied is not None:
                found.append(_first_passing(image, x, tied, FACTORS, images, up=up))
            if any(bound is not None for bound in found):
                break  # more rounds only while nothing passes
    passing = [bound for bound in found if bound is not None]
    if passing:
        return _tightest(passing, up=up)
    repaired = _repaired(image, _around(x, margin, FACTORS[-1], images, up=up), trivial, up=up)
    return trivial if repaired is None else repaired


def _near_enough(bound: FloatArray, x: FloatArray, *, up: bool) -> bool:
    """Whether *bound* lies within :data:`NEAR_ENOUGH` of the precision asked for
    (:func:`~veribattery.checker.certify.bounds.current_precision`) from *x* everywhere:
    tighter bounds from the tied rows' margin would buy nothing the caller needs."""
    relative, absolute = current_precision()
    allowed = np.maximum(relative * np.abs(x), absolute)
    with np.errstate(invalid="ignore"):
        gap = (bound - x) if up else (x - bound)
        return bool(np.all(gap <= NEAR_ENOUGH * allowed))


def _first_passing(image: Image, x: FloatArray, margin: FloatArray,
                   factors: tuple[float, ...], images: _Images, *, up: bool
                   ) -> FloatArray | None:
    """``x +- (c margin + slack)`` pushed, for the first factor *c* that passes."""
    trivial = images.top if up else images.floor
    for factor in factors:
        pushed = _pushed(image, _around(x, margin, factor, images, up=up), trivial, up=up)
        if pushed is not None:
            return pushed
    return None


def _tightest(bounds: list[FloatArray], *, up: bool) -> FloatArray:
    """The tightest of certified bounds on each state: each bounds the fixed point, so
    their minimum (maximum, below) does too (it need not pass the test itself, and
    interval iteration from it stays sound: ``B`` is monotone)."""
    reduce = np.minimum if up else np.maximum
    return np.asarray(reduce.reduce(np.stack(bounds)), dtype=np.float64)


def _pushed(image: Image, bound: FloatArray, trivial: FloatArray,
            *, up: bool) -> FloatArray | None:
    """*bound* moved outward where it fails its test, until every state passes.

    A state whose image lies beyond its bound is moved past the image by as much
    again: a row tied with the strategy's but with another distribution (which the
    margin does not cover) needs a little more room there, and its predecessors
    then absorb the change in their own margins. Every vector tried is tested
    whole; only one that passes everywhere is returned. Pushing stops early where
    many states keep failing (:data:`GIVE_UP_SHARE`).
    """
    bound = bound.copy()
    for done in range(PUSH_ROUNDS):
        mapped = image(bound)
        with np.errstate(invalid="ignore"):
            failing = ((mapped > bound) if up else (mapped < bound)) & (bound != trivial)
        at = np.flatnonzero(failing)
        if not at.size:
            return bound
        if done >= PUSH_PATIENCE and at.size > GIVE_UP_SHARE * bound.size:
            return None
        # Only the failing states move: the rounds after the first touch few of them.
        bound[at] = _moved_outward(mapped[at], bound[at], trivial[at], up=up)
    return None


def _moved_outward(mapped: FloatArray, bound: FloatArray, trivial: FloatArray,
                   *, up: bool) -> FloatArray:
    """Failing states' bounds moved past their images by as much again (clipped to
    *trivial*, which also replaces NaN)."""
    with np.errstate(invalid="ignore", over="ignore"):
        if up:
            moved = np.minimum(_above(mapped + (mapped - bound)), trivial)
        else:
            moved = np.maximum(step_down(mapped - (bound - mapped)), trivial)
    return np.where(np.isnan(moved), trivial, moved)


def _around(x: FloatArray, margin: FloatArray, factor: float, images: _Images,
            *, up: bool) -> FloatArray:
    """``x + (factor margin + slack)`` rounded up, or ``x - ...`` rounded down, clipped
    to the trivial bounds; exact zeros (value and margin 0) stay zeros."""
    slack = 4.0 * UNIT_ROUNDOFF * np.abs(x) + np.where((x == 0) & (margin == 0), 0.0, ETA)
    with np.errstate(invalid="ignore", over="ignore"):
        if up:
            bound = np.minimum(_above(x + factor * margin + slack), images.top)
            return np.where(np.isnan(bound), images.top, bound)
        bound = np.maximum(step_down(x - factor * margin - slack), images.floor)
    return np.where(np.isnan(bound), images.floor, bound)


def _passes(image: Image, bound: FloatArray, trivial: FloatArray, *, up: bool) -> bool:
    """Whether *bound* passes the fixed-point test everywhere.

    A state at its trivial bound needs no test: ``B(l) >= B(0) >= 0`` for a
    nonnegative map, and the ceiling is a pre-fixed point by the caller's contract.
    """
    mapped = image(bound)
    good: BoolArray = (mapped <= bound) if up else (mapped >= bound)
    return bool(np.all(good | (bound == trivial)))


def _above(total: FloatArray) -> FloatArray:
    """An upper bound of a sum of nonnegative terms computed as *total* (exact if 0)."""
    return np.where(total == 0, 0.0, step_up(total))


def _repaired(image: Image, bound: FloatArray, trivial: FloatArray,
              *, up: bool) -> FloatArray | None:
    """*bound* with the states that fail the test set to *trivial*, until all pass."""
    for _ in range(REPAIR_ROUNDS):
        mapped = image(bound)
        good: BoolArray = (mapped <= bound) if up else (mapped >= bound)
        good |= bound == trivial
        if good.all():
            return bound
        bound = np.where(good, bound, trivial)
    return None


def _tightened(system: ChoiceSystem, images: _Images, x: FloatArray, lower: FloatArray,
               upper: FloatArray, progress: Progress | None) -> tuple[FloatArray, FloatArray]:
    """Interval iteration from a certified pair until precise (or out of sweeps)."""
    sweeps = min(INTERVAL_SWEEPS, INTERVAL_WORK // max(1, 2 * system.off.nnz))
    for sweep in range(sweeps):
        if Bounds.around(x, lower, upper).precise_states().all():
            break
        lower = np.maximum(lower, images.lower(lower))
        upper = np.minimum(upper, images.upper(upper))
        if progress is not None:
            progress(sweep + 1, sweeps, "sweeps")
    return lower, upper
