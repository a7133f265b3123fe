"""A priori error bounds of computations on nonnegative numbers.

A sum of ``k`` nonnegative products, computed in floating point in any order, lies
within the factors ``1 +- g_k`` of its exact value, ``g_k = k u / (1 - k u)`` (Higham,
*Accuracy and Stability of Numerical Algorithms*, §3.1), as long as no product
underflows: one factor per vector instead of :func:`~.rounding.product_error`'s bound
per row, at a fraction of its cost, for bounds at most ``k u`` wider. Whether a product
can have underflowed is decided from the smallest positive factors
(:data:`NO_UNDERFLOW`); the callers fall back to the per-row enclosure where it can.
A computed 0 is then exact: every product of a nonzero probability and a nonzero
value is far from 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from veribattery._types import BoolArray, CsrMatrix, FloatArray
from veribattery.checker.certify.rounding import nonzero_terms, step_down, step_up

__all__ = ["NO_UNDERFLOW", "UNIT", "NonnegativeProducts", "float_above", "float_below", "gamma",
           "least_positive", "no_underflow", "zero_terms_only"]

#: The least a product of two nonzero factors may be for the a priori bounds: far above
#: the subnormals, where relative error bounds stop holding.
NO_UNDERFLOW = 2.0**-1000
#: The unit roundoff of float64, exactly.
UNIT = Fraction(1, 2**53)


def gamma(k: int) -> Fraction:
    """``g_k = k u / (1 - k u)``, exactly."""
    return k * UNIT / (1 - k * UNIT)


#: The bit pattern of ``+inf`` as an unsigned integer.
_INFINITY_PATTERN = np.uint64(0x7FF0000000000000)


def float_below(q: Fraction) -> float:
    """The largest double at most *q*."""
    nearest = float(q)
    return nearest if Fraction(nearest) <= q else math.nextafter(nearest, -math.inf)


def float_above(q: Fraction) -> float:
    """The smallest double at least *q*."""
    nearest = float(q)
    return nearest if Fraction(nearest) >= q else math.nextafter(nearest, math.inf)


def least_positive(values: FloatArray) -> float:
    """The smallest positive entry of *values* (``inf`` if none).

    On the doubles' bit patterns as unsigned integers, which order the positive ones as
    their values, with 1 subtracted: 0 wraps around to the largest, and -0.0, the
    negative numbers and NaN lie above ``+inf``'s pattern. One pass with no mask, where
    a masked minimum cost a step-bounded round of resource-gathering (B=1300) 1-7 ms.
    """
    patterns = np.ascontiguousarray(values, dtype=np.float64).view(np.uint64)
    if not patterns.size:
        return math.inf
    least = (patterns - np.uint64(1)).min()
    if least >= _INFINITY_PATTERN:
        return math.inf
    return float(np.array(least + np.uint64(1), dtype=np.uint64).view(np.float64))


def no_underflow(values: FloatArray, smallest: float) -> bool:
    """Whether no product of a probability of at least *smallest* and one of *values*
    (nonnegative) can underflow: each is 0 or at least :data:`NO_UNDERFLOW`."""
    return least_positive(values) * smallest >= NO_UNDERFLOW


def zero_terms_only(M: CsrMatrix, x: FloatArray, silent: BoolArray) -> BoolArray:
    """Of the rows *silent*, whose float product ``M x`` is 0, those whose every stored
    entry reads an ``x_j = 0``: their product is exactly 0, where
    :func:`~.rounding.enclose_product` counts every stored entry as a term that may have
    underflowed (the others did). Where no product can underflow, that is all of them;
    else the rows' nonzero terms are counted.

    (Not part of :func:`~.rounding.enclose_product`: the check costs a step-bounded
    iteration 10-15% of its time, for an exact 0 where its bound is ``2k ETA``.)
    """
    if no_underflow(np.abs(x), least_positive(M.data)):
        return silent
    return np.asarray(silent & (nonzero_terms(M, x) == 0), dtype=np.bool_)


@dataclass(frozen=True, slots=True)
class NonnegativeProducts:
    """Rigorous bounds of ``M x`` for a nonnegative *matrix* and nonnegative vectors.

    :param shrink: ``1 / (1 + g_k)`` rounded down, *k* the most entries of a row ...
    :param stretch: ... and ``1 / (1 - g_k)`` rounded up.
    :param smallest: the smallest positive entry of *matrix*.
    """

    matrix: CsrMatrix
    shrink: float
    stretch: float
    smallest: float

    @classmethod
    def of(cls, matrix: CsrMatrix) -> NonnegativeProducts:
        terms = int(np.diff(matrix.indptr).max(initial=0))
        return cls(matrix, float_below(1 / (1 + gamma(terms))),
                   float_above(1 / (1 - gamma(terms))), least_positive(matrix.data))

    def bound(self, x: FloatArray, *, up: bool) -> FloatArray | None:
        """A lower (upper, if *up*) bound of every row's ``M x``, exact where the
        computed product is 0; None where a product may have underflowed."""
        if not no_underflow(x, self.smallest):
            return None
        product = np.asarray(self.matrix @ x, dtype=np.float64)
        if up:
            return np.where(product == 0, 0.0, step_up(product * self.stretch))
        return np.maximum(step_down(product * self.shrink), 0.0)
