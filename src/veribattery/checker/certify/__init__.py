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

The modules: :mod:`~veribattery.checker.certify.bounds` (the :class:`Bounds` every
kernel returns, and the precision rules), :mod:`~veribattery.checker.certify.rounding`
(directed rounding, enclosed products), :mod:`~veribattery.checker.certify.affine` (the
enclosed fixed-point maps), :mod:`~veribattery.checker.certify.fixpoint` (their
certificates), :mod:`~veribattery.checker.certify.focus` (certificates at a few
states) and :mod:`~veribattery.checker.certify.horizon` (step bounds too large to
iterate). This package re-exports the public names of rounding, affine and fixpoint.
"""

from veribattery.checker.certify.affine import AffineMap, PinnedMap, RowPlans
from veribattery.checker.certify.fixpoint import (
    Correction,
    certify_fixpoint,
    certify_side,
    fixpoint_defect,
    interval_iteration,
    quick_certificate,
    spectral_cap,
)
from veribattery.checker.certify.rounding import (
    ETA,
    TERM_FLOOR,
    UNIT_ROUNDOFF,
    enclose_product,
    error_coefficient,
    nonzero_terms,
    product_error,
    row_terms,
    step_down,
    step_down_in_place,
    step_up,
    step_up_in_place,
    sums_at_most_one,
)

__all__ = [
    "ETA",
    "TERM_FLOOR",
    "UNIT_ROUNDOFF",
    "AffineMap",
    "Correction",
    "PinnedMap",
    "RowPlans",
    "certify_fixpoint",
    "certify_side",
    "enclose_product",
    "error_coefficient",
    "fixpoint_defect",
    "interval_iteration",
    "nonzero_terms",
    "product_error",
    "quick_certificate",
    "row_terms",
    "spectral_cap",
    "step_down",
    "step_down_in_place",
    "step_up",
    "step_up_in_place",
    "sums_at_most_one",
]
