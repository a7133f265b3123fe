"""Rigorous enclosures: floating-point matrix-vector products with an error bound, fixed points.

The argument (``docs/numerics.md``): a float64 product ``y = fl(M x)`` with a
nonnegative sparse *M* differs from the exact ``M x`` by at most
``gamma_k * (|M| |x|)_i + k * eta`` in row *i*, where *k* is the number of nonzero
terms of that row, ``gamma_k = k u / (1 - k u)`` with ``u = 2**-53``, and ``eta = 2**-1074``
covers underflow (Higham, *Accuracy and Stability of Numerical Algorithms*, §3.1
and §3.4; the bound holds for any order of summation and with fused
multiply-adds). :func:`product_error` evaluates a safe upper bound of that
quantity in floating point; :class:`AffineMap` uses it to enclose
``F(x) = offset + P x`` from below and above.

For the unbounded kernels, after the 0/1 pre-pass the fixed point ``x* = F(x*)``
on the unknown states is unique and ``F`` is monotone, so a vector *u* with
``F(u) <= u`` is an upper bound of ``x*`` and *l* with ``F(l) >= l`` a lower
bound (:func:`certify_fixpoint`); and from any certified pair, ``F`` applied to
each side stays certified (:func:`interval_iteration`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from veribattery._sparse import csr_sharing
from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker.bounds import Bounds, round_down, round_up

UNIT_ROUNDOFF = 2.0**-53
#: The smallest subnormal float64: the absolute error of one product that underflows.
ETA = 2.0**-1074
#: What :class:`AffineMap` adds to a row's rounding bound per term: it covers the
#: underflow of a product (``2 * ETA``) and keeps the bound a normal number, so that a
#: row whose numerator is exactly 0 (the no states of a shared system) does not make
#: the images compute on subnormals, which costs ~20x per operation on x86 (microcode
#: assists): half of a large certificate's time. ``2**-900`` is far below any precision.
TERM_FLOOR = 2.0**-900
#: Maps of fewer unknown states than this keep their per-row error constants.
KEEP_CONSTANTS_BELOW = 1_000_000
#: Safety factor on the computed error bound (covers the rounding of the bound itself).
_SAFETY = 1.0 + 2.0**-30
#: Interval-iteration sweeps tried before a result is returned as imprecise.
INTERVAL_SWEEPS = 2_000
#: ... unless the sweeps would cost more than this many nonzero visits in total.
INTERVAL_WORK = 400_000_000

#: Solves ``(I - P_mm) d = v`` approximately (None: not available).
Correction = Callable[[FloatArray], FloatArray | None]

#: ``u (1 + 2u)``, exact in float64: ``fl(c + fl(PHI |c| + ETA))`` is at least the
#: successor of *c* (Rump, Zimmermann, Boldo, Melquiond, BIT 49 (2009), Algorithm 2).
_PHI = 2.0**-53 + 2.0**-105


def step_up(c: FloatArray) -> FloatArray:
    """An upper bound of the successor of each entry, in three vectorised operations.

    :func:`~veribattery.checker.bounds.round_up` (``nextafter``) is exact but costs
    a libm call per entry; this is the same bound, at most one float further out.
    Valid for finite entries and ``+inf``; ``-inf`` gives NaN (callers exclude it).
    """
    return np.asarray(c + (_PHI * np.abs(c) + ETA), dtype=np.float64)


def step_up_in_place(c: FloatArray) -> None:
    """:func:`step_up` of *c* >= 0 (or NaN, +inf) into *c*: the same operations."""
    bump = c * _PHI
    bump += ETA
    c += bump


def step_down_in_place(c: FloatArray) -> None:
    """:func:`step_down` of *c* >= 0 (or NaN, +inf: NaN) into *c*: the same operations."""
    bump = c * _PHI
    bump += ETA
    c -= bump


def step_down(c: FloatArray) -> FloatArray:
    """A lower bound of the predecessor of each entry (see :func:`step_up`).

    Valid for finite entries and ``-inf``; ``+inf`` gives NaN.
    """
    return np.asarray(c - (_PHI * np.abs(c) + ETA), dtype=np.float64)


def row_terms(M: CsrMatrix) -> FloatArray:
    """Number of stored entries of each row of *M* (as floats, for the error bound)."""
    return np.asarray(np.diff(M.indptr), dtype=np.float64)


def product_error(magnitude: FloatArray, roundings: FloatArray,
                  underflows: FloatArray) -> FloatArray:
    """An upper bound of ``|fl(sum) - sum|`` for a row sum of products.

    :param magnitude: the float64-computed ``(|M| |x|)_i`` (plus any added ``|c_i|``).
    :param roundings: *k* in ``gamma_k``: the number of rounded operations a term
        passes through (nonzero terms, less one when the products are exact).
    :param underflows: the number of products that may underflow (0 when exact).
    """
    # gamma_k <= 2 k u while k u <= 1/2, and the computed magnitude underestimates
    # the exact one by at most a factor (1 - gamma_k): 4 k u covers both.
    with np.errstate(over="ignore", invalid="ignore"):
        bound = (4.0 * UNIT_ROUNDOFF) * roundings * magnitude * _SAFETY + underflows * (2 * ETA)
    bound = np.where(np.isnan(bound), np.inf, bound)
    return np.where(bound > 0, step_up(bound), 0.0)


def error_coefficient(roundings: FloatArray) -> FloatArray:
    """The factor of the magnitude in :func:`product_error` (``4 k u`` with its safety
    margin, rounded up), for callers that bound many products of the same rows."""
    product = (4.0 * UNIT_ROUNDOFF) * roundings * _SAFETY
    # For integer counts below 2**22 the product is exact (k 2**-51 + k 2**-81 spans
    # at most 52 bits), so it needs no rounding up: nextafter costs a libm call per
    # entry, and the certificate's images make this vector at every call.
    counts = np.asarray(roundings)
    if counts.size and float(np.max(counts)) < 2.0**22 and bool(
            np.all(counts >= 0)) and np.array_equal(np.trunc(counts), counts):
        return np.asarray(product, dtype=np.float64)
    return np.asarray(round_up(product), dtype=np.float64)


def enclose_product(M: CsrMatrix, x: FloatArray, offset: FloatArray | None = None,
                    terms: FloatArray | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``offset + M x`` in floating point, with a rigorous enclosure of its exact value.

    When *x* holds only zeros and ones the products are exact and only nonzero
    terms count, so a row with a single such term has no error at all;
    otherwise every stored entry of the row counts as a term.

    :param M: a sparse matrix with nonnegative entries.
    :param x: a float64 vector (taken as exact).
    :param offset: an optional vector added to the product.
    :param terms: ``row_terms(M)`` if already known.
    :return: ``(y, lower, upper)`` with ``lower <= offset + M x <= upper`` exactly.
    """
    with np.errstate(invalid="ignore"):
        y = np.asarray(M @ x, dtype=np.float64)
    magnitude = y if _nonnegative(x) else np.asarray(M @ np.abs(x), dtype=np.float64)
    exact = bool(np.all((x == 0) | (x == 1)))
    if exact:
        count = _nonzero_terms(M, x)
    elif terms is None:
        count = row_terms(M)
    else:
        count = terms
    if offset is not None:
        y = y + offset
        magnitude = magnitude + np.abs(offset)
        count = count + (offset != 0)
    roundings = np.maximum(count - 1.0, 0.0) if exact else count
    error = product_error(magnitude, roundings, np.zeros_like(y) if exact else count)
    with np.errstate(invalid="ignore"):  # (+inf stepped down or -inf up: NaN, mapped below)
        lower, upper = step_down(y - error), step_up(y + error)
    lower = np.where(error == 0, y, lower)
    upper = np.where(error == 0, y, upper)
    return y, np.where(np.isnan(lower), -np.inf, lower), np.where(np.isnan(upper), np.inf, upper)


def _nonzero_terms(M: CsrMatrix, x: FloatArray) -> FloatArray:
    """Per row, the stored entries of *M* whose column has ``x != 0``.

    One byte per nonzero of temporary memory (a matrix of ones would take eight).
    """
    hits = (x != 0)[M.indices]
    lengths = np.diff(M.indptr)
    counts = np.zeros(M.shape[0], dtype=np.float64)
    filled = lengths > 0
    if hits.size:
        sums = np.add.reduceat(hits, M.indptr[:-1][filled], dtype=np.int64)
        counts[filled] = sums
    return counts


def _nonnegative(x: FloatArray) -> bool:
    return bool(np.all(x >= 0))


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
           shared: AffineMap | None = None) -> AffineMap:
        """The map of the rows ``P[states, :]`` (all columns).

        :param offset: per-unknown constant (rewards), or None.
        :param shared: a map of the same *rows* and *states* whose row data (the
            off-diagonal matrix, leaving probabilities, error constants) to re-use.
        """
        if shared is not None:
            return dataclasses.replace(shared, known_lower=known_lower,
                                       known_upper=known_upper, offset=offset)
        plan = _row_plan(rows, states)
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


#: Plans kept (a sweep point's systems: the reward system and the recharge cap's), most
#: recent first, and the shapes of the last rows planned (a plan is kept for a shape seen
#: before: a sweep, not a single check, which would only pay its memory).
ROW_PLANS_KEPT = 2
_ROW_PLANS: list[_RowPlan] = []
_ROWS_SEEN: list[tuple[int, int, int, int]] = []


def _row_plan(rows: CsrMatrix, states: IntArray) -> _RowPlan:
    """The plan of *rows* and *states*: the kept one if it fits, else a new one (kept,
    with a copy of the pattern, when rows of this shape were planned recently: a sweep,
    not a single check, which would only pay its memory)."""
    for i, kept in enumerate(_ROW_PLANS):
        if kept.fits(rows, states):
            _ROW_PLANS.insert(0, _ROW_PLANS.pop(i))
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
    again = shape in _ROWS_SEEN
    pattern = (rows.indptr, rows.indices, states)
    plan = _RowPlan(tuple(a.copy() for a in pattern) if again else pattern,  # type: ignore[arg-type]
                    keep, rows.indices[keep], indptr, terms)
    if again:
        for array in (*plan.pattern, plan.keep, plan.indices, plan.indptr, plan.terms):
            array.flags.writeable = False  # shared by the maps of every point: never edited
        _ROW_PLANS[:] = [plan, *_ROW_PLANS][:ROW_PLANS_KEPT]
        _ROWS_SEEN.remove(shape)
    _ROWS_SEEN[:] = [shape, *_ROWS_SEEN][:2 * ROW_PLANS_KEPT]
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


def _fast(F: AffineMap, x: FloatArray) -> bool:
    """Whether *F*'s images at vectors like *x* may take the fast form (a nonnegative
    map and ``x >= 0``: :meth:`AffineMap.images` and :meth:`AffineMap.image`)."""
    return _fast_images(F) and F.nonnegative and bool(np.all(x >= 0))


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
                       value: FloatArray, precise: Callable[[Bounds], BoolArray]
                       ) -> tuple[FloatArray, FloatArray]:
    """Tighten certified bounds by applying *F* to each side until *precise* holds.

    Sound for any certified start: ``l <= x*`` implies ``F(l) <= F(x*) = x*``.

    :param precise: which states of a :class:`Bounds` meet the required precision.
    """
    sweeps = min(INTERVAL_SWEEPS, INTERVAL_WORK // max(1, 2 * F.rows.nnz))
    for _ in range(sweeps):
        if precise(Bounds.around(value, lower, upper)).all():
            break
        lower = np.maximum(lower, F.lower(lower))
        upper = np.minimum(upper, F.upper(upper))
    return lower, upper


def spectral_cap(M: CsrMatrix) -> float:
    """A rigorous upper bound of ``||M||_inf`` (the largest row sum, rounded up)."""
    if M.nnz == 0:
        return 0.0
    ones = np.ones(M.shape[1])
    return float(np.max(enclose_product(M, ones)[2]))
