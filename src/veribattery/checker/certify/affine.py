"""The fixed-point map ``F(x) = offset + P x`` on a system's unknown states, enclosed.

:class:`AffineMap` evaluates ``F`` from below and above with a certified error bound
per row (:mod:`~veribattery.checker.certify.rounding`); :class:`PinnedMap` holds some
rows at known values; :class:`RowPlans` keeps the maps' index work per sparsity
pattern for later matrices.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from veribattery._sparse import csr_sharing
from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker.certify.bounds import round_down, round_up
from veribattery.checker.certify.rounding import (
    TERM_FLOOR,
    enclose_product,
    error_coefficient,
    product_error,
    row_terms,
    step_down,
    step_down_in_place,
    step_up,
    step_up_in_place,
)

#: Maps of fewer unknown states than this keep their per-row error constants.
KEEP_CONSTANTS_BELOW = 1_000_000


@dataclass(frozen=True, slots=True)
class AffineMap:
    """The fixed-point map of the unknown *states*, self-loops divided out.

    With ``o_i`` the offset (rewards), ``P'`` the rows without their diagonal and
    ``s_i = sum_j P'_ij`` the probability of leaving state *i*, the map is
    ``G(x)_i = (o_i + sum_j P'_ij ext(x)_j) / s_i``: each row's self-loop is read
    as ``1 - s_i`` (exactly), as the linear solver reads it. ``ext(x)`` is the
    full state vector holding *x* on *states* and the known values elsewhere,
    those known as an interval ``[known_lower, known_upper]``. ``G`` is monotone
    in ``x`` and in the known values because ``P >= 0``.

    Build it with :meth:`of`.
    """

    rows: CsrMatrix
    states: IntArray
    known_lower: FloatArray
    known_upper: FloatArray
    offset: FloatArray | None
    leave_lower: FloatArray
    leave_upper: FloatArray
    #: :attr:`coefficient` and :attr:`underflow`, kept for maps of fewer than
    #: :data:`KEEP_CONSTANTS_BELOW` states (None: derived from ``rows`` at each use).
    constants: tuple[FloatArray, FloatArray] | None = None

    # On large maps the per-row constants below are derived from ``rows`` on each use
    # rather than stored: two vectors per map (22 MB at 1.4M states) against a few
    # vector operations per image. On smaller ones (a sweep point of the paper's
    # mission) those operations were a tenth of the certificate's time.

    @property
    def terms(self) -> FloatArray:
        """Number of stored entries of each row (:func:`row_terms` of ``rows``)."""
        return row_terms(self.rows)

    @property
    def coefficient(self) -> FloatArray:
        """Per row, ``coefficient * magnitude + underflow`` bounds the rounding of the
        numerator (:func:`product_error` with the offset always counted as a term,
        so it stays valid for any offset and known values a copy is given; each
        term's underflow counted as :data:`TERM_FLOOR`)."""
        return _error_constants(self.terms)[0]

    @property
    def underflow(self) -> FloatArray:
        """The underflow part of that bound (see :attr:`coefficient`)."""
        return _error_constants(self.terms)[1]

    @classmethod
    def of(cls, rows: CsrMatrix, states: IntArray, known_lower: FloatArray,
           known_upper: FloatArray, offset: FloatArray | None,
           shared: AffineMap | None = None, plans: RowPlans | None = None) -> AffineMap:
        """The map of the rows ``P[states, :]`` (all columns).

        :param offset: per-unknown constant (rewards), or None.
        :param shared: a map of the same *rows* and *states* whose row data (the
            off-diagonal matrix, leaving probabilities, error constants) to re-use.
        :param plans: where the index work is kept for rows of the same pattern
            (:class:`RowPlans`; None: nothing is kept).
        """
        if shared is not None:
            return dataclasses.replace(shared, known_lower=known_lower,
                                       known_upper=known_upper, offset=offset)
        plan = _row_plan(rows, states, plans)
        off = csr_sharing(rows.data[plan.keep], plan.indices, plan.indptr, rows.shape)
        leave_lower, leave_upper = _row_sum_bounds(off, plan.terms)
        constants = _error_constants(plan.terms) if states.size < KEEP_CONSTANTS_BELOW else None
        return cls(off, states, known_lower, known_upper, offset,
                   np.maximum(leave_lower, 0.0), leave_upper, constants)

    @property
    def nonnegative(self) -> bool:
        """Whether the offset and known values are >= 0 (then so is every image of x >= 0)."""
        offset_ok = self.offset is None or bool(np.all(self.offset >= 0))
        return offset_ok and bool(np.all(self.known_lower >= 0))

    def images(self, low: FloatArray, high: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(lower(low), upper(high))`` for finite ``0 <= low, high`` and a
        :attr:`nonnegative` map, with the cheap rounding of :func:`step_up`.

        Every term is nonnegative, so the magnitude of the numerator is the
        numerator itself and the exact quotient is at least 0.
        """
        if low is high and self.known_lower is self.known_upper:
            numerator, error = self._numerator_bound(low, self.known_lower)
            return self._below(numerator, error), self._above(numerator, error)
        return self.image(low, up=False), self.image(high, up=True)

    def image(self, x: FloatArray, *, up: bool) -> FloatArray:
        """One side of :meth:`images`: the upper image of *x* if *up*, else the lower."""
        numerator, error = self._numerator_bound(x, self.known_upper if up else self.known_lower)
        return self._above(numerator, error) if up else self._below(numerator, error)

    def _numerator_bound(self, x: FloatArray, known: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The float numerator at *x* and the bound of its rounding (both >= 0).

        The same operations as :func:`step_up` on the same operands, in place (the
        numerator and its error bound are >= 0, so ``|c| = c``).
        """
        full = known.copy()
        full[self.states] = x
        numerator = np.asarray(self.rows @ full, dtype=np.float64)
        del full
        if self.offset is not None:
            numerator += self.offset
        if self.constants is not None:
            coefficient, underflow = self.constants
            error = coefficient * numerator
            error += underflow
        else:
            terms = self.terms
            terms += 1.0
            error = error_coefficient(terms)
            error *= numerator
            terms *= TERM_FLOOR  # the underflow part
            error += terms
            del terms
        step_up_in_place(error)
        return numerator, error

    def _above(self, numerator: FloatArray, error: FloatArray) -> FloatArray:
        above = numerator + error
        with np.errstate(divide="ignore", invalid="ignore"):
            step_up_in_place(above)
            above /= self.leave_lower
            step_up_in_place(above)
        above[np.isnan(above)] = np.inf
        return above

    def _below(self, numerator: FloatArray, error: FloatArray) -> FloatArray:
        # The exact quotient is >= 0, so a negative bound is 0 whenever it is found:
        # clamping before each step down gives the bounds of ``step_down`` on the
        # nonnegative entries (then the cheaper in-place form applies) and 0 elsewhere.
        below = numerator - error
        np.maximum(below, 0.0, out=below)  # (NaN stays NaN)
        with np.errstate(divide="ignore", invalid="ignore"):
            step_down_in_place(below)
            below /= self.leave_upper
            np.maximum(below, 0.0, out=below)
            step_down_in_place(below)
        np.maximum(below, 0.0, out=below)
        undefined = np.isnan(below)
        if undefined.any():
            below[undefined] = -np.inf
        return below

    def constant_side(self, *, up: bool) -> FloatArray:
        """A bound of ``G(0)``, the constant ``c`` of ``G(x) = c + B x``: from above if
        *up*, else from below.

        Without known values (rewards to a target) the numerator is the offset itself,
        exactly, so only the division by the leaving probability is rounded.
        """
        o = self.offset
        known = self.known_upper if up else self.known_lower
        if o is not None and not known.any() and bool(np.all(o >= 0)):
            with np.errstate(divide="ignore", invalid="ignore"):  # s in [leave_lower, leave_upper]
                bound = o / (self.leave_lower if up else self.leave_upper)
            if up:
                step_up_in_place(bound)
                bound[np.isnan(bound)] = np.inf  # (0 / 0: a bound no state needs)
                return bound
            step_down_in_place(bound)
            return np.maximum(bound, 0.0)
        zeros = np.zeros(self.states.size)
        if _fast(self, zeros):
            return self.image(zeros, up=up)
        return self.upper(zeros) if up else self.lower(zeros)

    def _numerator(self, x: FloatArray, known: FloatArray) -> tuple[FloatArray, FloatArray]:
        full = known.copy()
        full[self.states] = x
        _, lower, upper = enclose_product(self.rows, full, self.offset, self.terms)
        return lower, upper

    def lower(self, x: FloatArray) -> FloatArray:
        """A certified lower bound of ``G(x)`` (with the known values at their lower bounds)."""
        low = self._numerator(x, self.known_lower)[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            quotient = np.where(low >= 0, low / self.leave_upper, low / self.leave_lower)
        return np.where(np.isnan(quotient), -np.inf, round_down(quotient))

    def upper(self, x: FloatArray) -> FloatArray:
        """A certified upper bound of ``G(x)`` (with the known values at their upper bounds)."""
        high = self._numerator(x, self.known_upper)[1]
        with np.errstate(divide="ignore", invalid="ignore"):
            quotient = np.where(high >= 0, high / self.leave_lower, high / self.leave_upper)
        return np.where(np.isnan(quotient), np.inf, round_up(quotient))


def _error_constants(terms: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:attr:`AffineMap.coefficient` and :attr:`AffineMap.underflow` of rows of *terms*
    stored entries (the offset counted as one more)."""
    counted = terms + 1.0
    return error_coefficient(counted), counted * TERM_FLOOR


@dataclass(frozen=True, slots=True)
class PinnedMap(AffineMap):
    """An :class:`AffineMap` whose states at the positions *pinned* have the fixed values
    *pinned_values*: ``G'(x)_i = v_i`` there, ``G(x)_i`` elsewhere (reading *x* at the
    pinned states too). Monotone as ``G``; its fixed point is that of the map of the
    other states with the pinned ones known (docs/numerics.md, "Shared systems")."""

    pinned: IntArray | None = None
    pinned_values: FloatArray | None = None

    @classmethod
    def around(cls, F: AffineMap, pinned: IntArray, values: FloatArray) -> PinnedMap:
        """*F* with the states at positions *pinned* fixed to *values*."""
        parts = {f.name: getattr(F, f.name) for f in dataclasses.fields(AffineMap)}
        return cls(**parts, pinned=pinned, pinned_values=values)

    def _pin(self, image: FloatArray) -> FloatArray:
        assert self.pinned is not None and self.pinned_values is not None
        image[self.pinned] = self.pinned_values
        return image

    def images(self, low: FloatArray, high: FloatArray) -> tuple[FloatArray, FloatArray]:
        below, above = AffineMap.images(self, low, high)
        return self._pin(below), self._pin(above)

    def image(self, x: FloatArray, *, up: bool) -> FloatArray:
        return self._pin(AffineMap.image(self, x, up=up))

    def lower(self, x: FloatArray) -> FloatArray:
        return self._pin(AffineMap.lower(self, x))

    def constant_side(self, *, up: bool) -> FloatArray:
        return self._pin(AffineMap.constant_side(self, up=up))

    def upper(self, x: FloatArray) -> FloatArray:
        return self._pin(AffineMap.upper(self, x))


@dataclasses.dataclass(frozen=True, slots=True, eq=False)
class _RowPlan:
    """The index work of :meth:`AffineMap.of` for one pattern of rows and unknown states:
    which stored entries are off the diagonal, and how many per row.

    A structure-reusing sweep builds the map of one pattern at every point (only the
    probabilities change), so the plan of the last pattern seen twice is kept; it is
    used for rows whose index arrays and states are equal to its own (compared).
    """

    pattern: tuple[IntArray, IntArray, IntArray]  # rows' indptr and indices, the states
    keep: BoolArray  # the stored entries off the diagonal
    indices: IntArray
    indptr: IntArray
    terms: FloatArray

    def fits(self, rows: CsrMatrix, states: IntArray) -> bool:
        """Whether *rows* and *states* have this plan's pattern."""
        indptr, indices, own = self.pattern
        return (np.array_equal(rows.indptr, indptr) and np.array_equal(rows.indices, indices)
                and np.array_equal(states, own))


#: Plans a :class:`RowPlans` keeps (a sweep point's systems: the reward system and the
#: recharge cap's).
ROW_PLANS_KEPT = 2


class RowPlans:
    """The index work of :meth:`AffineMap.of` kept for rows of the same pattern (a
    structure-reusing sweep builds the maps of one pattern at every point), held by a
    :class:`~veribattery.checker.workspace.Workspace`."""

    def __init__(self) -> None:
        #: The plans kept, most recent first.
        self.plans: list[_RowPlan] = []
        #: The shapes of the last rows planned: a plan is kept for a shape seen before
        #: (a sweep, not a single check, which would only pay its memory).
        self.seen: list[tuple[int, int, int, int]] = []

    @property
    def empty(self) -> bool:
        """Whether nothing is kept yet."""
        return not (self.plans or self.seen)


def _row_plan(rows: CsrMatrix, states: IntArray, plans: RowPlans | None) -> _RowPlan:
    """The plan of *rows* and *states*: the one kept in *plans* if it fits, else a new
    one (kept, with a copy of the pattern, when rows of this shape were planned recently:
    a sweep, not a single check, which would only pay its memory)."""
    kept_plans = [] if plans is None else plans.plans
    for i, kept in enumerate(kept_plans):
        if kept.fits(rows, states):
            kept_plans.insert(0, kept_plans.pop(i))
            return kept
    row_of = np.repeat(np.arange(rows.shape[0], dtype=rows.indices.dtype),
                       np.diff(rows.indptr))
    keep = rows.indices != states[row_of]  # one byte per entry: large systems pass here
    lengths = np.bincount(row_of[keep], minlength=rows.shape[0])
    del row_of
    indptr = np.zeros(rows.shape[0] + 1, dtype=rows.indptr.dtype)
    np.cumsum(lengths, out=indptr[1:])
    terms = np.asarray(lengths, dtype=np.float64)
    shape = (*rows.shape, rows.nnz, states.size)
    again = plans is not None and shape in plans.seen
    pattern = (rows.indptr, rows.indices, states)
    plan = _RowPlan(tuple(a.copy() for a in pattern) if again else pattern,  # type: ignore[arg-type]
                    keep, rows.indices[keep], indptr, terms)
    if plans is None:
        return plan
    if again:
        for array in (*plan.pattern, plan.keep, plan.indices, plan.indptr, plan.terms):
            array.flags.writeable = False  # shared by the maps of every point: never edited
        plans.plans[:] = [plan, *plans.plans][:ROW_PLANS_KEPT]
        plans.seen.remove(shape)
    plans.seen[:] = [shape, *plans.seen][:2 * ROW_PLANS_KEPT]
    return plan


def _row_sum_bounds(off: sp.csr_matrix, terms: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:func:`enclose_product` of *off* with a vector of ones (*terms*: its stored entries
    per row), its lower and upper bounds: the same operations, without finding the terms."""
    y = np.asarray(off @ np.ones(off.shape[1]), dtype=np.float64)
    error = product_error(y, np.maximum(terms - 1.0, 0.0), np.zeros_like(y))
    with np.errstate(invalid="ignore"):
        lower, upper = step_down(y - error), step_up(y + error)
    lower = np.where(error == 0, y, lower)
    upper = np.where(error == 0, y, upper)
    return np.where(np.isnan(lower), -np.inf, lower), np.where(np.isnan(upper), np.inf, upper)


def _fast_images(F: AffineMap) -> bool:
    """Whether ``F.images`` agrees with ``F.lower``/``F.upper``: a subclass that
    overrides those must override :meth:`AffineMap.images` too to get the fast path."""
    kind = type(F)
    own = kind.lower is AffineMap.lower and kind.upper is AffineMap.upper
    return own or kind.images is not AffineMap.images

def _fast(F: AffineMap, x: FloatArray) -> bool:
    """Whether *F*'s images at vectors like *x* may take the fast form (a nonnegative
    map and ``x >= 0``: :meth:`AffineMap.images` and :meth:`AffineMap.image`)."""
    return _fast_images(F) and F.nonnegative and bool(np.all(x >= 0))
