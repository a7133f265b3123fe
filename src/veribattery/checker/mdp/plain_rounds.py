"""Step-bounded rounds in plain floating point, bounded a priori.

A round of :mod:`~veribattery.checker.mdp.stepped` computes ``opt_a (o_a + P_a x)``
on nonnegative numbers only: products, sums, a maximum or minimum. From an exact start
(and exact values where the states do not move) its computed value lies within the
factors ``1 +- g_T`` of the exact image of the values it read (Higham, *Accuracy and
Stability of Numerical Algorithms*, §3.1; *T* the most terms of a row, its offset
counted), the optimum keeps them, and the map is monotone with ``F(c x) <= c F(x)``
for ``c >= 1`` (and ``>=`` for ``c <= 1``: the offsets are nonnegative). By induction a
computed value ``y`` after *k* rounds lies in ``[(1 - g)^k x, (1 + g)^k x]`` of the
exact one, so ``x`` lies in ``[y (1 - k g), y / (1 - k g)]``. That holds while no
product underflows, checked before every round
(:func:`~veribattery.checker.certify.apriori.no_underflow`), and while every value is
finite. An exact 0 stays 0.

One product a round instead of two (the point values and their error radius, each
enclosed row by row): on resource-gathering (B=1300, 958,894 states)
``Rmax=? [ C<=B ]`` took 58 s with the radius. Where the bounds would be wider than
:data:`SHARE` of the precision asked for, or a value underflows or overflows, the
caller carries the radius instead.
"""

from __future__ import annotations

from collections.abc import Callable
from fractions import Fraction

import numpy as np

from veribattery._types import BoolArray, FloatArray, RankArray
from veribattery.checker.certify import step_down, step_up
from veribattery.checker.certify.apriori import (
    float_above,
    float_below,
    gamma,
    least_positive,
    no_underflow,
)
from veribattery.checker.certify.bounds import Bounds, current_precision
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.mdp.levels import ChoiceLevels
from veribattery.checker.mdp.system import Objective

__all__ = ["plain_rounds"]

#: The a priori bounds are used where their relative width, about ``2 k g``, is at most
#: this share of the relative precision asked for.
SHARE = Fraction(1, 8)


def plain_rounds(levels: ChoiceLevels, start: FloatArray, held: FloatArray,
                 moving: BoolArray, offset: FloatArray | None, objective: Objective,
                 steps: int, decide: Callable[[RankArray], None],
                 progress: Progress | None = None) -> Bounds | None:
    """Bounds after *steps* rounds from the exact *start* (in *levels*' order; the
    states not *moving* hold their exact value in *held*), each round's choices told to
    *decide* (as ranks), or None where the a priori bounds do not apply (then what was
    told is void). *progress* is told ``(rounds done, steps, "steps")``."""
    matrix = levels.matrix
    terms = max(1, int(np.diff(matrix.indptr).max(initial=0)) + (offset is not None))
    spread = steps * gamma(terms)
    relative, _ = current_precision()
    if 2 * spread > SHARE * Fraction(relative) or spread >= 1:
        return None
    smallest = least_positive(matrix.data)
    reduce = np.maximum if objective == "max" else np.minimum
    everywhere = bool(moving.all())
    value = start
    for done in range(1, steps + 1):
        if not no_underflow(value, smallest):
            return None
        images = np.asarray(matrix @ value, dtype=np.float64)
        if offset is not None:
            with np.errstate(over="ignore"):
                images += offset
        best = levels.optimum(images, reduce)
        rank = levels.first_attaining(images, best)
        following = best if everywhere else np.where(moving, best, held)
        decide(rank if everywhere else np.where(moving, rank, 0))
        if np.array_equal(following, value):
            break  # (every later round is this one)
        value = following
        if progress is not None:
            progress(done, steps, "steps")
    if not bool(np.all(np.isfinite(value))):
        return None
    return _widened(value, moving, spread)


def _widened(value: FloatArray, moving: BoolArray, spread: Fraction) -> Bounds:
    """*value* with the moving states' a priori bounds (the others exact)."""
    shrink, stretch = float_below(1 - spread), float_above(1 / (1 - spread))
    lower, upper = value.copy(), value.copy()
    lower[moving] = np.maximum(step_down(value[moving] * shrink), 0.0)
    upper[moving] = np.where(value[moving] == 0, 0.0, step_up(value[moving] * stretch))
    return Bounds(value, lower, upper)

