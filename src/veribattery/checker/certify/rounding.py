"""Directed rounding and enclosed matrix-vector products.

:func:`step_up` and :func:`step_down` move a float64 vector to a neighbour at least one
ulp away; :func:`product_error` bounds the rounding error of a sparse product
``fl(M x)`` (Higham, *Accuracy and Stability of Numerical Algorithms*, §3.1 and §3.4),
and :func:`enclose_product` turns a product into a certified enclosure.
:func:`sums_at_most_one` decides exactly which rows of a matrix sum to at most 1.
"""

from __future__ import annotations

import numpy as np

from veribattery._types import BoolArray, CsrMatrix, FloatArray
from veribattery.checker.certify.bounds import round_up

UNIT_ROUNDOFF = 2.0**-53
#: The smallest subnormal float64: the absolute error of one product that underflows.
ETA = 2.0**-1074
#: What :class:`AffineMap` adds to a row's rounding bound per term: it covers the
#: underflow of a product (``2 * ETA``) and keeps the bound a normal number, so that a
#: row whose numerator is exactly 0 (the no states of a shared system) does not make
#: the images compute on subnormals, which costs ~20x per operation on x86 (microcode
#: assists): half of a large certificate's time. ``2**-900`` is far below any precision.
TERM_FLOOR = 2.0**-900
#: Safety factor on the computed error bound (covers the rounding of the bound itself).
_SAFETY = 1.0 + 2.0**-30

#: Error bounds at least this large absorb the underflow term (:func:`product_error`) ...
_NORMAL_BOUND = 2.0**-900
#: ... of at most this many products.
_MANY_UNDERFLOWS = 2.0**100

#: ``u (1 + 2u)``, exact in float64: ``fl(c + fl(PHI |c| + ETA))`` is at least the
#: successor of *c* (Rump, Zimmermann, Boldo, Melquiond, BIT 49 (2009), Algorithm 2).
_PHI = 2.0**-53 + 2.0**-105


def step_up(c: FloatArray) -> FloatArray:
    """An upper bound of the successor of each entry, in three vectorised operations.

    :func:`~veribattery.checker.certify.bounds.round_up` (``nextafter``) is exact but costs
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
    # (in place after the first product: the same operations, one vector fewer per step)
    with np.errstate(over="ignore", invalid="ignore"):
        bound = _scaled(np.multiply(4.0 * UNIT_ROUNDOFF, roundings), magnitude)
        bound *= _SAFETY
        # The underflow term f 2 ETA is subnormal, and making it costs ~20x per entry
        # (microcode assists: most of a Bellman image's time). Where the bound b is at
        # least 2**-900 and f at most 2**100, f 2 ETA <= 2**-973 is below half an ulp
        # of b (>= 2**-954), so b + f 2 ETA rounds to b: it is added elsewhere only.
        tiny = ~((bound >= _NORMAL_BOUND) & (np.asarray(underflows) <= _MANY_UNDERFLOWS))
        if np.any(tiny):
            bound[tiny] += np.broadcast_to(underflows, bound.shape)[tiny] * (2 * ETA)
    bound[np.isnan(bound)] = np.inf
    positive = bound > 0
    with np.errstate(over="ignore", invalid="ignore"):
        step_up_in_place(bound)  # (the entries that are not positive are replaced)
    bound[~positive] = 0.0
    return bound


def _scaled(factor: FloatArray, magnitude: FloatArray) -> FloatArray:
    """``factor * magnitude`` as float64, in *factor*'s storage where it is a vector of
    that shape and type (the same products, without a second vector of the rows at the
    certificate's peak)."""
    if (isinstance(factor, np.ndarray) and factor.dtype == np.float64
            and np.result_type(magnitude) == np.float64
            and factor.shape == np.shape(magnitude)):
        factor *= magnitude
        return factor
    return np.asarray(factor * magnitude, dtype=np.float64)


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
        count = nonzero_terms(M, x)
    elif terms is None:
        count = row_terms(M)
    else:
        count = terms
    if offset is not None:
        with np.errstate(over="ignore"):  # beyond the doubles: inf, enclosed as such below
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


def nonzero_terms(M: CsrMatrix, x: FloatArray | BoolArray) -> FloatArray:
    """Per row, the stored entries of *M* whose column has ``x != 0`` (as floats, as the
    terms of a product are counted).

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


def sums_at_most_one(M: CsrMatrix) -> BoolArray:
    """Per row of *M* (nonnegative), whether the exact sum of its stored entries is at
    most 1.

    The enclosed float sum decides most rows; a row whose enclosure holds 1 (every row
    that sums to exactly 1, for one) is summed again in rationals, its entries' dyadic
    values (:class:`gmpy2.mpq`, over object arrays).
    """
    _, low, high = enclose_product(M, np.ones(M.shape[1]))
    result = np.asarray(high <= 1.0, dtype=np.bool_)
    unsure = np.flatnonzero(~result & (low <= 1.0))
    if unsure.size:  # (at least two entries each: one entry's sum is exact)
        from gmpy2 import mpq

        rows = M[unsure]
        exact = np.frompyfunc(mpq, 1, 1)(rows.data)
        sums = np.add.reduceat(exact, rows.indptr[:-1])
        result[unsure] = np.asarray(sums <= 1, dtype=np.bool_)
    return result
