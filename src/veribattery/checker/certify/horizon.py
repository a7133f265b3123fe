"""Step bounds too large to iterate: how many rounds run, and what encloses the rest.

A step-bounded kernel (``U<=k``, ``C<=k``, ``I=k``; DTMC and MDP alike) runs one round
per step. A bound up to :data:`ROUND_LIMIT` is iterated in full, as always (or to a
fixed point, which every later round repeats). A larger one -- ``F<=10^15`` -- runs at
most :func:`rounds` rounds; the steps not run are then enclosed by what the kernel's
:class:`Trend` knows of its exact iterates: nondecreasing (a lower bound holds for all
later steps), and bounded by a ceiling (``U<=k`` below the unbounded ``U``). Every
value enclosed is nonnegative. ``docs/numerics.md``, "Step bounds beyond the rounds
run", gives the argument.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from veribattery._types import FloatArray
from veribattery.checker.certify.bounds import Bounds, round_up

__all__ = [
    "NONNEGATIVE",
    "RISING",
    "ROUND_LIMIT",
    "Trend",
    "beyond",
    "checkpoint",
    "drifted",
    "early",
    "meet",
    "rounds",
]

#: Bounds up to this many steps are iterated in full, as asked.
ROUND_LIMIT = 1_000_000
#: Larger ones run at most this many rounds (a round of a two-state chain takes
#: ~0.1 ms: ten seconds) ...
BEYOND_ROUNDS = 100_000
#: ... and visit at most this many stored entries (rounds times nonzeros) ...
WORK_LIMIT = 10**9
#: ... but run at least this many rounds: where the enclosure is first tried.
FIRST_CHECK = 1024


@dataclass(frozen=True, slots=True)
class Trend:
    """What is known of a step-bounded kernel's exact iterates (all nonnegative).

    :param rising: they are nondecreasing in the step, so a certified lower bound of
        one holds for every later step.
    :param ceiling: finds an upper bound of every iterate, or None when none is
        provable; called when first needed, at most once (:meth:`up_to`).
    """

    rising: bool = False
    ceiling: Callable[[], FloatArray | None] | None = None

    @classmethod
    def up_to(cls, find: Callable[[], FloatArray | None]) -> Trend:
        """Nondecreasing iterates bounded by what *find* returns (found once)."""
        return cls(True, functools.cache(find))

    @property
    def known(self) -> bool:
        """Whether this trend says more than "nonnegative"."""
        return self.rising or self.ceiling is not None


#: Iterates known to be nonnegative, nothing more.
NONNEGATIVE = Trend()
#: Nondecreasing iterates without a ceiling: ``C<=k`` (rewards are nonnegative).
RISING = Trend(rising=True)


def rounds(k: int, nonzeros: int) -> int:
    """The rounds to run for a bound of *k* steps on a matrix of *nonzeros* entries."""
    if k <= ROUND_LIMIT:
        return k
    return min(BEYOND_ROUNDS, max(FIRST_CHECK, WORK_LIMIT // max(nonzeros, 1)))


def checkpoint(done: int, k: int) -> bool:
    """Whether to try :func:`early` after *done* rounds of a bound of *k* steps: only
    for bounds beyond :data:`ROUND_LIMIT`, at powers of two from :data:`FIRST_CHECK`."""
    return k > ROUND_LIMIT and done >= FIRST_CHECK and done & (done - 1) == 0


def drifted(radius: FloatArray, grown: FloatArray, rho: float, remaining: int) -> FloatArray:
    """An error radius *remaining* rounds after one of radius *radius*, when the values
    no longer change and only the radius moves (to *grown* in the next round).

    With the values fixed, each round's error is at most ``M e + delta`` (a matrix of
    norm at most *rho* >= 1, a fixed rounding bound), so with ``d = (grown - radius)+``
    the error *j* rounds on is at most ``radius + sum_{i<j} rho^i max(d)``, at most
    ``radius + j rho^j max(d)``; ``d = 0`` leaves *radius* itself (a post-fixpoint).
    """
    with np.errstate(invalid="ignore"):
        creep = np.where(grown <= radius, 0.0, round_up(grown - radius))
    top = float(np.max(creep, initial=0.0))
    if top == 0.0 or remaining == 0:
        return radius
    try:
        growth = rho**remaining * _POW_SLACK  # (pow is not rounded up)
    except OverflowError:
        growth = math.inf
    extra = math.nextafter(math.nextafter(growth * remaining, math.inf) * top, math.inf)
    return round_up(radius + extra)


#: Covers the rounding of ``rho ** n`` (a few ulps in any libm).
_POW_SLACK = 1.0 + 2.0**-40


def beyond(value: FloatArray, lower: FloatArray, trend: Trend) -> Bounds:
    """Bounds of every later step, from the current iterate's *value* and certified
    *lower* bound: that lower bound if the iterates rise (else 0), the ceiling (else
    infinity)."""
    floor = np.maximum(lower, 0.0) if trend.rising else np.zeros_like(value)
    top = trend.ceiling() if trend.ceiling is not None else None
    if top is None:
        top = np.full_like(value, np.inf)
    return Bounds.around(value, floor, top)


def early(value: FloatArray, lower: FloatArray, trend: Trend) -> Bounds | None:
    """:func:`beyond` if the trend has a ceiling and that enclosure meets the required
    precision in every state (the rounds left need not run), else None."""
    if trend.ceiling is None or trend.ceiling() is None:
        return None
    found = beyond(value, lower, trend)
    return found if bool(found.precise_states().all()) else None


def meet(found: Bounds, value: FloatArray, lower: FloatArray, trend: Trend) -> Bounds:
    """*found* (bounds of step *k*) narrowed by :func:`beyond` of an earlier iterate;
    *found* itself when the trend knows nothing more."""
    if not trend.known:
        return found
    other = beyond(value, lower, trend)
    return Bounds.around(found.value, np.maximum(found.lower, other.lower),
                         np.minimum(found.upper, other.upper))
