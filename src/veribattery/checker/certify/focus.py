"""Certified bounds at a few states (the initial ones) from one transposed solve.

When only the answers at the initial states are read (``check``, ``prism``, a sweep
point), a whole vector of certified bounds is more than is needed. With ``G(x) = c + B x``
the fixed-point map of the unknown states (``B = D^-1 P'``, self-loops divided out) and
``x`` any approximation, ``x* - x = N (G(x) - x)`` exactly, ``N = (I - B)^-1 >= 0``; so

    |x*_k - x_k| <= sum_j N_kj |G(x) - x|_j <= w . d

for any ``w`` bounding row *k* of *N* from above and ``d`` the enclosed defect
(:func:`~veribattery.checker.certify.fixpoint.fixpoint_defect`). Row *k* of *N* is the fixed
point of the monotone map ``H(w) = e_k + B^T w``, so a ``w`` with ``H(w) <= w``
(tested in float64 on a rigorous upper enclosure) bounds it, as in ``certify``.
One such ``w`` per system serves every query solved on it: the same ``B``, whatever
the offset and known values, and also a pinned copy of it, whose ``B`` has rows
zeroed and so a smaller ``N`` (docs/numerics.md, "Bounds at the initial states").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from veribattery._types import BoolArray, FloatArray
from veribattery.checker.certify.affine import AffineMap
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.certify.fixpoint import fixpoint_defect
from veribattery.checker.certify.rounding import (
    TERM_FLOOR,
    UNIT_ROUNDOFF,
    error_coefficient,
    step_down,
    step_down_in_place,
    step_up,
    step_up_in_place,
)

#: Focus states beyond this many: the whole vector is certified instead (each costs
#: two transposed solves and four images, about what a whole certificate of a query costs).
FOCUS_MAX = 1
#: Margin factors tried for a row's certificate, in turn.
_FACTORS = (2.0, 16.0)
#: Safety factor on computed error bounds (as in ``certify``).
_SAFETY = 1.0 + 2.0**-30

#: Approximately solves ``w^T (I - B) = v^T`` (``Factorization.dual``).
DualSolve = Callable[[FloatArray], FloatArray | None]


@dataclass(frozen=True, slots=True)
class FocusRow:
    """Certified bounds of row *position* of ``(I - B)^-1``, for the system whose map's
    unknown states hold the focus state at *position*: *upper* from above, *lower*
    from below (None: not certified, or not valid for the map at hand)."""

    position: int
    upper: FloatArray
    lower: FloatArray | None

    def above_only(self) -> FocusRow:
        """This row for a pinned copy of its system (``B' <= B``, so ``N' <= N``: the
        upper bound holds for it, the lower one does not)."""
        return FocusRow(self.position, self.upper, None)


def certified_row(F: AffineMap, solve: DualSolve, position: int) -> FocusRow | None:
    """Row *position* of ``(I - B)^-1`` bounded from above and, where the test allows,
    from below, certified; None when the upper bound fails its test (then the caller
    certifies whole vectors).

    One margin serves both sides: ``w`` is moved by a multiple of the solved gap of the
    worse side, as :func:`~veribattery.checker.certify.fixpoint.quick_certificate` does. Each
    image is made and tested in turn (at 1.4M states every vector is 11 MB, and this
    runs at a property's peak).

    :param F: a map of the system (only its rows and leaving probabilities are read).
    :param solve: the system's transposed solver.
    """
    unit = np.zeros(F.states.size)
    unit[position] = 1.0
    w = solve(unit)
    if w is None:
        return None
    np.maximum(w, 0.0, out=w)
    reached = w != 0
    terms = _ImageTerms.of(F, reached, position)
    gap = _transposed_image(F, w, terms, up=True)
    gap -= w
    np.maximum(gap, w - _transposed_image(F, w, terms, up=False), out=gap)
    np.maximum(gap, 0.0, out=gap)
    gap = _up(gap)
    margin = solve(gap) if np.all(np.isfinite(gap)) else None
    if margin is None:
        return None
    np.maximum(margin, gap, out=margin)
    del gap
    for factor in _FACTORS:
        spread = margin * factor
        spread += (4.0 * UNIT_ROUNDOFF) * w
        upper = _up(w + spread)
        if not np.array_equal(upper != 0, reached):  # (upper >= w: more terms, or none)
            terms = _ImageTerms.of(F, upper != 0, position)
        if not np.all(_transposed_image(F, upper, terms, up=True) <= upper):
            continue
        lower = w - spread
        del spread
        lower = np.maximum(step_down(lower), 0.0)
        below = bool(np.all(_transposed_image(F, lower, terms, up=False) >= lower))
        return FocusRow(position, upper, lower if below else None)
    return None


def _up(c: FloatArray) -> FloatArray:
    """:func:`step_up` of ``c >= 0``, keeping exact zeros: a weight of 0 (a state the
    focus state does not reach) must stay 0, or the images of its successors would gain
    the underflow terms of nonzero products and fail their test."""
    return np.where(c > 0, step_up(c), c)


@dataclass(frozen=True, slots=True)
class _ImageTerms:
    """The rounding bound of the sums ``(B^T w)_j`` for the *w* of one nonzero pattern:
    ``coefficient * sum + underflow`` per unknown state, and the focus *position*."""

    coefficient: FloatArray
    underflow: FloatArray
    position: int

    @classmethod
    def of(cls, F: AffineMap, nonzero: BoolArray, position: int) -> _ImageTerms:
        """The terms of the images of every ``w`` that is nonzero at most at *nonzero*:
        per column, the stored entries ``P'_ij`` with ``nonzero[i]`` (counted, not
        weighted), and the focus position's 1."""
        rows = F.rows
        columns = rows.indices
        if not nonzero.all():  # the entries of the nonzero rows only
            columns = columns[np.repeat(nonzero, np.diff(rows.indptr))]
        counts = np.bincount(columns, minlength=rows.shape[1])[F.states].astype(np.float64)
        counts[position] += 1.0
        return cls(error_coefficient(counts), counts * TERM_FLOOR, position)


def _transposed_image(F: AffineMap, w: FloatArray, terms: _ImageTerms, *,
                      up: bool) -> FloatArray:
    """A rigorous bound of ``H(w) = e_position + B^T w``: from above if *up*, else from
    below (``w >= 0``, nonzero only where *terms* count).

    ``(B^T w)_j = sum_i P'_ij w_i / s_i``: each quotient is bounded first (``s_i`` by its
    lower bound above, its upper bound below), then each sum of nonnegative products is
    enclosed with its nonzero terms counted (exact zeros leave no rounding), so a state
    no focus path reaches keeps the image 0 its weight has.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        quotient = w / (F.leave_lower if up else F.leave_upper)
    if up:
        quotient = _up(quotient)
        unbounded = np.isnan(quotient)  # 0 / 0 where w is 0 (exactly 0: every state leaves)
        if unbounded.any():
            quotient[unbounded] = np.where(w[unbounded] == 0, 0.0, np.inf)
    else:
        step_down_in_place(quotient)
        np.maximum(quotient, 0.0, out=quotient)
    total = np.asarray(F.rows.T @ quotient, dtype=np.float64)[F.states]
    del quotient
    total[terms.position] += 1.0
    error = terms.coefficient * total
    error += terms.underflow
    step_up_in_place(error)
    if up:
        total += error
        step_up_in_place(total)
        return total
    total -= error
    np.maximum(total, 0.0, out=total)
    step_down_in_place(total)
    np.maximum(total, 0.0, out=total)
    return total


def answered_bounds(F: AffineMap, rows: Sequence[FocusRow], rhs: FloatArray,
                    floor: FloatArray, ceiling: FloatArray) -> Bounds | None:
    """Bounds of the fixed point of *F* tight at the *rows*' positions, without a solve:
    ``x*_k = sum_j N_kj c_j`` with ``c = G(0)`` (the offset and known values, enclosed)
    and row *k* of ``N`` between the row's bounds. Elsewhere the trivial *floor* and
    *ceiling* (and a value of 0 clipped into them). None when a position misses the
    required precision.

    :param rows: rows bounded on both sides, of *F*'s own ``B``.
    :param rhs: the system's right-hand side ``b`` (``c = b / s``), for the point value.
    """
    n = F.states.size
    lower = np.array(np.broadcast_to(floor, (n,)))
    upper = np.array(np.broadcast_to(ceiling, (n,)))
    value = np.minimum(np.maximum(0.0, lower), upper)
    for row in rows:
        assert row.lower is not None
        k = row.position
        at_least = _row_sum(row, F.constant_side(up=False), up=False)
        at_most = _row_sum(row, F.constant_side(up=True), up=True)
        lower[k], upper[k] = max(at_least, float(lower[k])), min(at_most, float(upper[k]))
        # The value: the middle of the row times b / s, the solver's own right-hand side
        # (as a solve's x_k, to within a few ulps), not the middle of the interval.
        with np.errstate(divide="ignore", invalid="ignore"):
            middle = row.lower + row.upper
            middle *= rhs
            middle /= F.leave_lower + F.leave_upper
        middle[row.upper == 0] = 0.0  # (N_kj = 0 exactly, whatever b_j is)
        estimate = _pairwise(middle)[0]
        del middle
        value[k] = min(max(estimate, lower[k]), upper[k]) if math.isfinite(estimate) else (
            lower[k])
    found = Bounds(value, lower, upper)
    return found if _precise_at(found, [row.position for row in rows]) else None


def _row_sum(row: FocusRow, c: FloatArray, *, up: bool) -> float:
    """A bound of ``sum_j N_kj c_j`` for ``N_k`` between the *row*'s bounds: from above
    if *up* (its upper side where ``c_j >= 0``, its lower one where ``c_j < 0``), else
    from below (the other way round)."""
    assert row.lower is not None
    near, far = (row.upper, row.lower) if up else (row.lower, row.upper)
    least = float(np.min(c))
    if not (math.isfinite(least) and math.isfinite(float(np.max(c)))):
        # N_kj = 0 exactly where the upper bound is 0 (and c_j may be infinite there).
        reached = np.flatnonzero(row.upper)
        near, far, c = near[reached], far[reached], c[reached]
    with np.errstate(invalid="ignore"):  # (0 * inf: NaN, an unbounded sum)
        products = near * c if least >= 0 else np.where(c >= 0, near * c, far * c)
    low, high = _sum_bounds(products)
    return high if up else low


def _sum_bounds(products: FloatArray) -> tuple[float, float]:
    """Bounds of the exact sum of the exact products that *products* rounded.

    The sum is taken pairwise by halving, so each term meets ``L = ceil(log2 n)``
    additions: with the product's own rounding, ``|error| <= gamma_(L+1) sum |t|``
    (Higham §3.1 and §4.2) plus each product's underflow; ``2 (L+1) u`` covers
    ``gamma_(L+1)`` and the computed magnitude's own shortfall.
    """
    total, levels = _pairwise(products)
    magnitude = total if total >= 0 and bool(np.all(products >= 0)) else (
        _pairwise(np.abs(products))[0])
    if not (math.isfinite(total) and math.isfinite(magnitude)):
        return -math.inf, math.inf
    error = (2.0 * UNIT_ROUNDOFF) * (levels + 1) * magnitude * _SAFETY + products.size * 2.0**-1074
    error = math.nextafter(error, math.inf)
    return (math.nextafter(total - error, -math.inf), math.nextafter(total + error, math.inf))


def _pairwise(terms: FloatArray) -> tuple[float, int]:
    """The sum of *terms* by halving (adjacent pairs, zeros padded to a power of two),
    and the number of halvings: an order whose rounding is bounded by its depth."""
    if terms.size <= 1:
        return (float(terms[0]) if terms.size else 0.0), 0
    levels = (terms.size - 1).bit_length()
    padded = np.zeros(1 << levels)  # zeros add exactly
    padded[:terms.size] = terms
    for _ in range(levels):
        padded = padded[0::2] + padded[1::2]
    return float(padded[0]), levels


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
            radius = _sum_bounds(row.upper * defect)[1]  # (both >= 0; inf if unbounded)
            k = row.position
            lower[k] = max(math.nextafter(float(x[k]) - radius, -math.inf), float(lower[k]))
            upper[k] = min(math.nextafter(float(x[k]) + radius, math.inf), float(upper[k]))
    found = Bounds.around(x, lower, upper)
    positions = [row.position for row in rows]
    if not _precise_at(found, positions):
        return None
    return found


def _precise_at(found: Bounds, positions: list[int]) -> bool:
    """Whether the bounds at *positions* meet the required precision."""
    if not positions:
        return True
    at = np.asarray(positions)
    part = Bounds(found.value[at], found.lower[at], found.upper[at])
    return bool(part.precise_states().all())
