"""Certified bounds at a few states (the initial ones) from one transposed solve.

When only the answers at the initial states are read (``check``, ``prism``, a sweep
point), a whole vector of certified bounds is more than is needed. With ``G(x) = c + B x``
the fixed-point map of the unknown states (``B = D^-1 P'``, self-loops divided out) and
``x`` any approximation, ``x* - x = N (G(x) - x)`` exactly, ``N = (I - B)^-1 >= 0``; so

    |x*_k - x_k| <= sum_j N_kj |G(x) - x|_j <= w . d

for any ``w`` bounding row *k* of *N* from above and ``d`` the enclosed defect
(:func:`~veribattery.checker.certify.fixpoint_defect`). Row *k* of *N* is the fixed
point of the monotone map ``H(w) = e_k + B^T w``, so a ``w`` with ``H(w) <= w``
(tested in float64 on a rigorous upper enclosure) bounds it, as in ``certify``.
One such ``w`` per system serves every query solved on it: the same ``B``, whatever
the offset and known values, and also a pinned copy of it, whose ``B`` has rows
zeroed and so a smaller ``N`` (docs/numerics.md, "Bounds at the initial states").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from veribattery._record import record
from veribattery._types import FloatArray
from veribattery.checker.bounds import Bounds
from veribattery.checker.certify import (
    TERM_FLOOR,
    UNIT_ROUNDOFF,
    AffineMap,
    error_coefficient,
    fixpoint_defect,
    step_up,
)

#: Focus states beyond this many: the whole vector is certified instead (each costs
#: two transposed solves and two products, about what a whole certificate of a query costs).
FOCUS_MAX = 1
#: Margin factors tried for a row's certificate, in turn.
_FACTORS = (2.0, 16.0)
#: Safety factor on computed error bounds (as in ``certify``).
_SAFETY = 1.0 + 2.0**-30

#: Approximately solves ``w^T (I - B) = v^T`` (``Factorization.dual``).
DualSolve = Callable[[FloatArray], FloatArray | None]


@record
class FocusRow:
    """A certified upper bound *weights* of row *position* of ``(I - B)^-1``, for the
    system whose map's unknown states hold the focus state at *position*."""

    position: int
    weights: FloatArray


def certified_row(F: AffineMap, solve: DualSolve, position: int) -> FocusRow | None:
    """Row *position* of ``(I - B)^-1`` bounded from above, certified; None when the
    approximation fails its test (then the caller certifies whole vectors).

    :param F: a map of the system (only its rows and leaving probabilities are read).
    :param solve: the system's transposed solver.
    """
    unit = np.zeros(F.states.size)
    unit[position] = 1.0
    w = solve(unit)
    if w is None:
        return None
    np.maximum(w, 0.0, out=w)
    gap = _up(np.maximum(_transposed_image(F, w, position) - w, 0.0))
    margin = solve(gap) if np.all(np.isfinite(gap)) else None
    if margin is None:
        return None
    np.maximum(margin, gap, out=margin)
    for factor in _FACTORS:
        candidate = _up(w + factor * margin + (4.0 * UNIT_ROUNDOFF) * w)
        if np.all(_transposed_image(F, candidate, position) <= candidate):
            return FocusRow(position, candidate)
    return None


def _up(c: FloatArray) -> FloatArray:
    """:func:`step_up` of ``c >= 0``, keeping exact zeros: a weight of 0 (a state the
    focus state does not reach) must stay 0, or the images of its successors would gain
    the underflow terms of nonzero products and fail their test."""
    return np.where(c > 0, step_up(c), c)


def _transposed_image(F: AffineMap, w: FloatArray, position: int) -> FloatArray:
    """A rigorous upper bound of ``H(w) = e_position + B^T w`` for ``w >= 0``.

    ``(B^T w)_j = sum_i P'_ij w_i / s_i``: each quotient is bounded above first (``s_i``
    by its lower bound), then the sum of nonnegative products is enclosed with its
    terms counted per column: only the nonzero ones (exact zeros leave no rounding), so
    a state no focus path reaches keeps the image 0 its weight has.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        quotient = _up(w / F.leave_lower)
    quotient[w == 0] = 0.0  # exactly: every unknown state leaves (s_i > 0), bounded or not
    quotient[np.isnan(quotient)] = np.inf
    columns = F.rows.T  # (a view: CSC of the transpose)
    total = np.asarray(columns @ quotient, dtype=np.float64)[F.states]
    terms = np.asarray(columns @ (quotient != 0).astype(np.float64),
                       dtype=np.float64)[F.states]
    total[position] += 1.0
    terms[position] += 1.0
    error = error_coefficient(terms) * total
    error += terms * TERM_FLOOR  # the underflow of each nonzero product
    image = total + step_up(error)
    return step_up(image)


def focused_bounds(F: AffineMap, x: FloatArray, rows: Sequence[FocusRow],
                   floor: FloatArray, ceiling: FloatArray) -> Bounds | None:
    """Bounds of the fixed point of *F* that are tight at the *rows*' positions and the
    trivial *floor*/*ceiling* elsewhere (valid there too); None unless every focus
    position meets the required precision.

    :param x: the approximate fixed point (finite).
    """
    lower = np.broadcast_to(floor, x.shape).copy()
    upper = np.broadcast_to(ceiling, x.shape).copy()
    if rows:
        defect = fixpoint_defect(F, x)
        for row in rows:
            radius = _weighted_sum_up(row.weights, defect)
            k = row.position
            lower[k] = max(math.nextafter(float(x[k]) - radius, -math.inf), float(lower[k]))
            upper[k] = min(math.nextafter(float(x[k]) + radius, math.inf), float(upper[k]))
    found = Bounds.around(x, lower, upper)
    positions = [row.position for row in rows]
    if not _precise_at(found, positions):
        return None
    return found


def _weighted_sum_up(weights: FloatArray, defect: FloatArray) -> float:
    """An upper bound of ``sum_j weights_j defect_j`` (both >= 0): the float dot product
    plus Higham's bound for ``n`` terms (any order), the underflows, rounded up."""
    if not np.all(np.isfinite(defect)):
        return math.inf
    total = float(np.sum(weights * defect))  # (numpy's own sum: a BLAS dot may spawn threads)
    n = float(weights.size)
    error = 4.0 * UNIT_ROUNDOFF * n * total * _SAFETY + n * 2.0**-1073
    return math.nextafter(math.nextafter(total + math.nextafter(error, math.inf), math.inf),
                          math.inf)


def _precise_at(found: Bounds, positions: list[int]) -> bool:
    """Whether the bounds at *positions* meet the required precision."""
    if not positions:
        return True
    at = np.asarray(positions)
    part = Bounds(found.value[at], found.lower[at], found.upper[at])
    return bool(part.precise_states().all())
