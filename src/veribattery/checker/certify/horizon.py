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

from veribattery._types import CsrMatrix, FloatArray
from veribattery.checker.certify.bounds import Bounds, round_down, round_up

__all__ = [
    "GAINING",
    "NONNEGATIVE",
    "RISING",
    "ROUND_LIMIT",
    "Trend",
    "beyond",
    "checkpoint",
    "drifted",
    "early",
    "gain_checkpoint",
    "gained",
    "meet",
    "power_range",
    "rounds",
    "row_sum_bounds",
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
    #: The map is ``opt_a (o_a + P_a x)`` over every state (``C<=k``): its steps can be
    #: carried forward by :func:`gained`.
    gaining: bool = False

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
#: ... whose map is ``opt_a (o_a + P_a x)`` over every state (:func:`gained`).
GAINING = Trend(rising=True, gaining=True)


def rounds(k: int, nonzeros: int) -> int:
    """The rounds to run for a bound of *k* steps on a matrix of *nonzeros* entries."""
    if k <= ROUND_LIMIT:
        return k
    return min(BEYOND_ROUNDS, max(FIRST_CHECK, WORK_LIMIT // max(nonzeros, 1)))


def gain_checkpoint(done: int, k: int) -> bool:
    """Whether to try :func:`gained` after *done* rounds of a bound of *k* steps: at
    powers of two from :data:`FIRST_CHECK`, whatever the bound, while rounds remain."""
    return FIRST_CHECK <= done < k and done & (done - 1) == 0


def gained(start: tuple[FloatArray, FloatArray], step: tuple[FloatArray, FloatArray],
           remaining: int, sums: tuple[float, float]) -> Bounds | None:
    """Bounds of the iterate *remaining* rounds after *start* (value, error radius) of a
    map ``T(x) = opt_a (o_a + P_a x)`` over every state, from the next computed iterate
    and the rounding of that one step (*step*: ``y ~ T(x)``, ``|y - T(x)| <= delta``);
    None where they are not finite.

    *sums* bound the rows' sums of the ``P_a`` (``l`` below the smallest, ``h`` above the
    largest). T is monotone, and for ``c >= 0`` ``T(x) + c min(l, 1) <= T(x + c) <=
    T(x) + c max(h, 1)``. So the exact orbit ``Y`` from the computed *x* (taken as exact)
    and the true one ``X`` stay within ``R max(h,1)^i`` of each other (``R``: the largest
    radius), and with ``Y_1 - Y_0`` enclosed by *delta* in ``[c, C]`` (made nonnegative,
    as the iterates of a nonnegative reward rise), ``Y_1 + c j min(l,1)^j <= Y_(1+j) <=
    Y_1 + C j max(h,1)^j``. Where the steps have become the same in every state (the gain
    of a unichain model), the rounds left need not run; only one step's rounding, not
    the accumulated radius, widens the step (``C - c``).
    """
    (x, radius), (y, delta) = start, step
    with np.errstate(invalid="ignore", over="ignore"):
        low1, high1 = round_down(y - delta), round_up(y + delta)
        least = float(np.min(round_down(low1 - x), initial=np.inf))
        most = float(np.max(round_up(high1 - x), initial=0.0))
    widest = float(np.max(radius, initial=0.0))
    if not all(math.isfinite(v) for v in (least, most, widest)) or not bool(
            np.all(np.isfinite(high1))):
        return None
    rounds = remaining - 1
    try:
        growth = max(sums[1], 1.0) ** remaining * _POW_SLACK
        shrink = min(sums[0], 1.0) ** rounds / _POW_SLACK
    except OverflowError:
        return None
    carried = math.nextafter(widest * growth, math.inf)
    up = math.nextafter(math.nextafter(max(most, 0.0) * rounds, math.inf) * growth, math.inf)
    down = math.nextafter(math.nextafter(max(least, 0.0) * rounds, -math.inf) * shrink,
                          -math.inf)
    upper = round_up(round_up(high1 + up) + carried)
    floor = np.maximum(round_down(x - radius), 0.0)  # (rising: the start's lower bound)
    lower = np.maximum(round_down(round_down(low1 + max(down, 0.0)) - carried), floor)
    return Bounds.around(y + rounds * (y - x), lower, upper)


def row_sum_bounds(M: CsrMatrix) -> tuple[float, float]:
    """A lower bound of the smallest row sum of *M* and an upper bound of the largest,
    for :func:`gained`, summed in extended precision: a bound a double's ulp from 1
    loses ``j * ulp`` of a value carried *j* rounds (10^-10 relative after 10^6 rounds,
    where the float enclosure's few ulps lost 10^-9, the precision asked)."""
    low, high = _row_sum_range(M)
    return math.nextafter(float(low), -math.inf), math.nextafter(float(high), math.inf)


def _row_sum_range(M: CsrMatrix) -> tuple[np.longdouble, np.longdouble]:
    """:func:`row_sum_bounds` before rounding to doubles: in extended precision."""
    if M.nnz == 0:
        return np.longdouble(0), np.longdouble(0)
    lengths = np.diff(M.indptr)
    sums = np.zeros(M.shape[0], dtype=np.longdouble)
    filled = lengths > 0
    sums[filled] = np.add.reduceat(M.data.astype(np.longdouble), M.indptr[:-1][filled])
    terms = int(lengths.max())
    unit = np.finfo(np.longdouble).eps / 2
    gamma = terms * unit / (1 - terms * unit)
    return np.min(sums) * (1 - gamma), np.max(sums) * (1 + gamma)


def power_range(M: CsrMatrix, lowest: float, highest: float, k: int) -> tuple[float, float]:
    """Bounds of ``M^k r`` for every *r* within ``[lowest, highest]``, *M* nonnegative
    (``I=k``: under any strategy a weighted sum of the states' rewards).

    ``M^k 1`` lies between the smallest and largest row sums' ``k``-th powers. Rows
    that sum to 1 in the reals may not in their doubles, so the range is the rewards'
    own only to within those powers, taken in extended precision (where a row of
    doubles summing to 1 keeps ``(1 + 2^-63)^k``, about e at ``k = 2^63``)."""
    small, large = _row_sum_range(M)
    with np.errstate(over="ignore", under="ignore"):
        grow = float(np.power(large, k) * _POW_SLACK)  # (pow is not rounded up)
        shrink = float(np.power(max(small, np.longdouble(0)), k) / _POW_SLACK)
    top = 0.0 if highest == 0 else highest * (grow if highest > 0 else shrink)
    bottom = 0.0 if lowest == 0 else lowest * (shrink if lowest > 0 else grow)
    return (bottom and math.nextafter(bottom, -math.inf)), (top and math.nextafter(top, math.inf))


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
