"""Certificates of fixed points: bounds of ``x* = F(x*)`` from an approximate solution.

After the 0/1 pre-pass the fixed point on the unknown states is unique and ``F`` is
monotone, so a vector *u* with ``F(u) <= u`` is an upper bound of ``x*`` and *l* with
``F(l) >= l`` a lower bound (:func:`certify_fixpoint`, :func:`quick_certificate`); from
any certified pair, ``F`` applied to each side stays certified
(:func:`interval_iteration`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from veribattery._types import BoolArray, CsrMatrix, FloatArray
from veribattery.checker.certify.affine import _fast
from veribattery.checker.certify.bounds import Bounds, round_down, round_up
from veribattery.checker.certify.rounding import (
    ETA,
    UNIT_ROUNDOFF,
    enclose_product,
    step_down,
    step_up,
)

if TYPE_CHECKING:
    from veribattery.checker.certify.affine import AffineMap


#: Interval-iteration sweeps tried before a result is returned as imprecise.
INTERVAL_SWEEPS = 2_000
#: ... unless the sweeps would cost more than this many nonzero visits in total.
INTERVAL_WORK = 400_000_000

#: Solves ``(I - P_mm) d = v`` approximately (None: not available).
Correction = Callable[[FloatArray], FloatArray | None]
#: Told ``(done, total, unit)`` as a long loop goes (a ``linalg.SolveMonitor`` is one).
Progress = Callable[[int, int, str], None]

def quick_certificate(F: AffineMap, x: FloatArray, correct: Correction | None,
                      floor: FloatArray, ceiling: FloatArray
                      ) -> tuple[FloatArray, FloatArray] | None:
    """:func:`certify_fixpoint`'s first candidate pair, tested once, or None.

    The common case of a good approximation *x*: the defect
    of *x* (one product), the margin ``d`` from one substitution (*correct*), then
    ``u = x + 2 d + slack`` and ``l = x - 2 d - slack`` tested together (one
    pass over both vectors; for a nonnegative :class:`AffineMap` with the cheap
    rounding of :func:`step_up`, otherwise with the map's own ``lower``/``upper``).
    Valid exactly as :func:`certify_fixpoint`: a vector that
    passes ``F(u) <= u`` bounds the fixed point from above, whatever produced it.
    None when any state fails or the data are outside this case; the caller then
    runs :func:`certify_fixpoint`.
    """
    if correct is None or not np.all(np.isfinite(x)):
        return None
    images, fast = _image_pair(F, x)
    # Temporaries are dropped as soon as they are used: at 10^6 states each is 8 MB
    # and this runs at the peak of a property's memory.
    defect = _defect(*images(x, x), x)
    margin = correct(defect) if np.all(np.isfinite(defect)) else None
    if margin is None or not np.all(np.isfinite(margin)):
        return None
    margin = np.maximum(margin, defect)  # (a new array: the solver's may be kept)
    del defect
    margin *= 2.0
    slack = 4.0 * UNIT_ROUNDOFF * np.abs(x) + ETA
    # With a nonnegative map 0 passes the lower test itself: F(0) >= 0.
    bottom = np.maximum(floor, 0.0) if fast else floor
    upper = x + margin  # x + 2 d + slack, then x - 2 d - slack, summed in that order
    upper += slack
    upper = np.minimum(step_up(upper), ceiling)
    lower = x - margin
    del margin
    lower -= slack
    del slack
    lower = np.maximum(step_down(lower), bottom)
    if not np.all(np.isfinite(upper)):
        return None
    image_low, image_high = images(lower, upper)
    # Where a bound sits at the trivial one it needs no test: l >= bottom gives
    # F(l) >= F(bottom) >= bottom exactly (and u <= ceiling likewise), whereas the
    # enclosure of F(ceiling) is a few ulps above it.
    if not np.all((image_high <= upper) | (upper == ceiling)):
        return None
    del image_high
    if np.all((image_low >= lower) | (lower == bottom)):
        return lower, upper
    return None


ImagePair = Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]


def _image_pair(F: AffineMap, x: FloatArray) -> tuple[ImagePair, bool]:
    """``(lower(low), upper(high))`` of *F* for vectors like *x*, and whether that is the
    fast form (a nonnegative map and ``x >= 0``: :meth:`AffineMap.images`)."""
    fast = _fast(F, x)
    return (F.images if fast else (lambda lo, hi: (F.lower(lo), F.upper(hi)))), fast


def fixpoint_defect(F: AffineMap, x: FloatArray) -> FloatArray:
    """A rigorous upper bound of ``|G(x) - x|`` per state (*x* finite), for the exact
    map ``G`` that *F* encloses (any offset and known values within its intervals)."""
    images, _ = _image_pair(F, x)
    return _defect(*images(x, x), x)


def _defect(low: FloatArray, high: FloatArray, x: FloatArray) -> FloatArray:
    """``step_up(max(high - x, x - low, 0))``, computed in *high*'s and *low*'s memory."""
    high -= x
    np.subtract(x, low, out=low)
    np.maximum(high, low, out=high)
    del low
    np.maximum(high, 0.0, out=high)
    return step_up(high)


def certify_fixpoint(F: AffineMap, x: FloatArray, correct: Correction | None,
                     floor: FloatArray, ceiling: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Certified bounds of the unique fixed point of *F* near the approximation *x*.

    The defect ``|F(x) - x|`` (enclosed rigorously) is pushed through an
    approximate inverse of ``I - P`` (*correct*) to a margin *d*; then
    ``u = x + c d`` and ``l = x - c d`` for growing *c* are tested for
    ``F(u) <= u`` and ``F(l) >= l``. States where a test fails fall back to
    *ceiling* / *floor* (trivial bounds that satisfy the tests themselves, e.g.
    1 and 0 for probabilities) and the test is repeated.

    :param F: the monotone affine map whose fixed point is sought.
    :param x: an approximate fixed point.
    :param correct: approximate solver of ``(I - P_mm) d = v``, or None.
    :param floor: trivial lower bounds (``F(floor) >= floor``), e.g. zeros.
    :param ceiling: trivial upper bounds (``F(ceiling) <= ceiling``), e.g. ones or inf.
    :return: ``(lower, upper)``, both certified.
    """
    quick = quick_certificate(F, x, correct, floor, ceiling)
    if quick is not None:
        return quick
    defect = round_up(np.maximum(F.upper(x) - x, x - F.lower(x)))
    defect = np.where(np.isfinite(defect), defect, np.inf)
    margin = correct(defect) if correct is not None and np.all(np.isfinite(defect)) else None
    margin = defect if margin is None or not np.all(np.isfinite(margin)) else margin
    margin = np.maximum(np.maximum(margin, defect), 0.0)
    slack = 4.0 * UNIT_ROUNDOFF * np.abs(x) + ETA
    upper = _first_certified(F.upper, lambda c: round_up(x + c * margin + slack), ceiling, up=True)
    lower = _first_certified(F.lower, lambda c: round_down(x - c * margin - slack), floor,
                             up=False)
    return np.maximum(lower, floor), np.minimum(upper, ceiling)


def certify_side(F: AffineMap, x: FloatArray, correct: Correction | None,
                 trivial: FloatArray, *, up: bool) -> FloatArray:
    """One certified bound of the fixed point of *F*: an upper bound if *up*, else a lower.

    For maps whose two sides have different fixed points (known values or offsets
    given as intervals), *x* should approximate the fixed point of that side
    (``F.upper`` or ``F.lower``): the margin then only covers *x*'s own defect, not
    the distance between the two sides, as :func:`certify_fixpoint` would.

    :param trivial: the bound used where the test fails (it must pass the test itself).
    """
    image = F.upper if up else F.lower
    with np.errstate(invalid="ignore"):
        gap = image(x) - x if up else x - image(x)
    defect = round_up(np.maximum(gap, 0.0))
    defect = np.where(np.isfinite(defect), defect, np.inf)
    margin = correct(defect) if correct is not None and np.all(np.isfinite(defect)) else None
    margin = defect if margin is None or not np.all(np.isfinite(margin)) else margin
    margin = np.maximum(np.maximum(margin, defect), 0.0)
    slack = 4.0 * UNIT_ROUNDOFF * np.abs(x) + ETA
    if up:
        bound = _first_certified(image, lambda c: round_up(x + c * margin + slack), trivial,
                                 up=True)
        return np.minimum(bound, trivial)
    bound = _first_certified(image, lambda c: round_down(x - c * margin - slack), trivial,
                             up=False)
    return np.maximum(bound, trivial)


def _first_certified(image: Callable[[FloatArray], FloatArray],
                     candidate: Callable[[float], FloatArray], trivial: FloatArray,
                     *, up: bool) -> FloatArray:
    """The first candidate (margin factors 2, 16, 1024) that passes the fixed-point test."""
    for factor in (2.0, 16.0, 1024.0):
        bound = _repair(image, candidate(factor), trivial, up=up)
        if bound is not None:
            return bound
    return trivial


def _repair(image: Callable[[FloatArray], FloatArray], bound: FloatArray,
            trivial: FloatArray, *, up: bool, rounds: int = 4) -> FloatArray | None:
    """*bound* with failing states set to *trivial* until the whole vector passes."""
    for _ in range(rounds):
        mapped = image(bound)
        good: BoolArray = mapped <= bound if up else mapped >= bound
        if good.all():
            return bound
        bound = np.where(good, bound, trivial)
    return None


def interval_iteration(F: AffineMap, lower: FloatArray, upper: FloatArray,
                       value: FloatArray, precise: Callable[[Bounds], BoolArray],
                       progress: Progress | None = None) -> tuple[FloatArray, FloatArray]:
    """Tighten certified bounds by applying *F* to each side until *precise* holds.

    Sound for any certified start: ``l <= x*`` implies ``F(l) <= F(x*) = x*``.

    :param precise: which states of a :class:`Bounds` meet the required precision.
    :param progress: told ``(sweeps done, most sweeps, "sweeps")`` after each sweep.
    """
    sweeps = min(INTERVAL_SWEEPS, INTERVAL_WORK // max(1, 2 * F.rows.nnz))
    for sweep in range(sweeps):
        if precise(Bounds.around(value, lower, upper)).all():
            break
        lower = np.maximum(lower, F.lower(lower))
        upper = np.minimum(upper, F.upper(upper))
        if progress is not None:
            progress(sweep + 1, sweeps, "sweeps")
    return lower, upper


def spectral_cap(M: CsrMatrix) -> float:
    """A rigorous upper bound of ``||M||_inf`` (the largest row sum, rounded up)."""
    if M.nnz == 0:
        return 0.0
    ones = np.ones(M.shape[1])
    return float(np.max(enclose_product(M, ones)[2]))
