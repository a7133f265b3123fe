"""Reward-bounded reachability, fast path: float64 levels with a forward-error radius.

The backward programme of :mod:`~veribattery.checker.kernels.reward_bounded` computed once in
float64, each state carrying a radius ``e >= |computed - exact|`` (the exact value of
the model as built). The argument is in ``docs/numerics.md`` ("Reward-bounded
reachability"); in short:

* a state with reward ``r > 0`` takes ``fl(B v_{k-r})``, whose distance to the exact
  value is at most the rounding of that product plus ``B e_{k-r}``;
* the zero-reward closure ``y = G(y)`` of a level is solved by one substitution with
  the factors; the computed ``y`` is within ``A^-1 (P_out e_out + D |y - G(y)|)`` of the
  exact closure (``A = D - P'`` the closure's system, ``A^-1 >= 0``), which is bounded
  by one more substitution plus its own defect times ``tau = A^-1 D 1``, the expected
  number of moves inside the closure, certified once per model;
* states from which the target needs more reward than the level allows are exactly 0.

All radius arithmetic is on nonnegative numbers rounded upward by a factor
(:data:`_UP`) and a normal floor per term (:data:`_FLOOR`), so no subnormal numbers
(slow on x86) and no ``nextafter`` in the loop.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery._unique import distinct
from veribattery.checker import certify, linalg
from veribattery.checker.certify.bounds import Bounds, round_down, round_up

if TYPE_CHECKING:
    from veribattery.checker.kernels.reward_bounded import Levels

#: Multiplying a nonnegative result of at most 7 rounded operations by this bounds
#: the exact value from above: ``(1 + u)^8 < 1 + 2^-50`` with ``u = 2^-53``.
_UP = 1.0 + 2.0**-50
#: Added once per term of a row: covers underflow of each product (at most
#: ``2^-1074``) and of the rounding-bound arithmetic, and keeps every radius, and its
#: product with a rounding coefficient (``>= 2^-53``), a normal number: subnormal
#: arithmetic is ~100x slower on x86. Negligible against any precision asked for.
_FLOOR = 2.0**-900
#: A closure solved by one substitution is re-solved with refinement when its
#: defect times ``tau`` exceeds this, relative to its largest value.
_REFINE_AT = 2.0**-44


def radius_programme(P: CsrMatrix, moving: BoolArray, target: BoolArray, rewards: IntArray,
                     levels: Levels, last: int) -> Bounds | None:
    """Levels ``0..last`` in float64 with a certified radius per state.

    Targets (1) and the states that are neither moving nor targets (0) are exact and
    never written again, so the two level vectors are reused from level to level.

    :param moving: the states that are neither targets nor unable to reach them.
    :param rewards: the reward of each state, a multiple of ``levels.unit`` where moving.
    :return: certified bounds of the last level, or None when ``tau`` could not be
        certified finite (then the caller certifies every level instead).
    """
    closure = None
    if levels.closure is not None:
        closure = _RadiusClosure.of(levels)
        if closure is None:
            return None
    steps = [_RadiusGroup.of(P, r, states) for r, states in levels.groups]
    value, radius = target.astype(np.float64), np.zeros(P.shape[0])
    for k in range(last + 1):
        for group in steps:
            group.fill(k, value, radius)
        if closure is not None:
            closure.close(levels, value, radius)
        for group in steps:
            group.remember(k, value, radius)
    beyond = _minimal_rewards(P, moving, target, rewards // levels.unit) > last
    value[beyond] = radius[beyond] = 0.0
    return _bounds(value, radius)


def _as_slice(states: IntArray) -> slice | IntArray:
    """Sorted *states* as a slice if they are contiguous (cheaper to read and write)."""
    if states.size and states[-1] - states[0] + 1 == states.size:
        return slice(int(states[0]), int(states[-1]) + 1)
    return states


def _widen(x: FloatArray) -> FloatArray:
    """Nonnegative constants enlarged by ``UP^2`` (rounded up), so that a result of at
    most 3 rounded operations on nonnegative numbers with them stays an upper bound."""
    return np.asarray(round_up(round_up(x * _UP) * _UP), dtype=np.float64)


def _bounds(value: FloatArray, radius: FloatArray) -> Bounds:
    """``value ± radius``, rounded outward and clipped to [0, 1] (exact where radius is 0)."""
    lower = np.where(radius == 0, value, np.maximum(round_down(value - radius), 0.0))
    upper = np.where(radius == 0, value, np.minimum(round_up(value + radius), 1.0))
    return Bounds.around(value, lower, upper)


def group_rows(P: CsrMatrix, states: IntArray
               ) -> tuple[IntArray, CsrMatrix, FloatArray, FloatArray]:
    """The rows of *states* over the columns they use, and their rounding-bound constants.

    :return: ``(successors, block, coefficient, underflow)``: :func:`certify.product_error`
        for nonnegative terms is at most ``coefficient * magnitude + underflow``.
    """
    rows = sp.csr_matrix(P[states])
    successors = distinct(rows.indices)
    block = sp.csr_matrix(rows[:, successors])
    terms = certify.row_terms(block)
    return successors, block, certify.error_coefficient(terms), terms * (2 * certify.ETA)


@dataclass(frozen=True, slots=True)
class _RadiusGroup:
    """States with reward *r*: value ``B v_{k-r}``, radius ``B e_{k-r}`` plus rounding.

    *history* holds the successors' values and radii of the last *r* levels, a ring
    buffer of ``(2, successors)`` arrays (two one-column products are much faster than
    one two-column product in scipy).
    """

    r: int
    #: The states, as a slice where they are contiguous.
    states: slice | IntArray
    successors: IntArray
    block: CsrMatrix
    history: FloatArray
    #: ``(c, 1 + c)`` with a margin for 3 roundings, ``c`` the largest ``4 k u`` of
    #: :func:`certify.product_error` over the rows: radius = weights . (value, radius).
    weights: FloatArray
    #: The largest :data:`_FLOOR` per term of a row, twice (once for each product).
    floor: float

    @classmethod
    def of(cls, P: CsrMatrix, r: int, states: IntArray) -> _RadiusGroup:
        successors, block, coefficient, _ = group_rows(P, states)
        c = float(coefficient.max(initial=0.0))
        weights = _widen(round_up(np.array([c, 1.0 + c])))
        floor = float(_widen(np.array([certify.row_terms(block).max(initial=0.0)
                                       * (2 * _FLOOR)]))[0])
        return cls(r, _as_slice(states), successors, block, np.zeros((r, 2, successors.size)),
                   weights, floor)

    def fill(self, k: int, value: FloatArray, radius: FloatArray) -> None:
        """Write this group's values and radii on level *k* (exactly 0 below level r).

        ``|fl(B v) - B v_exact| <= rounding of fl(B v) + B e``, and ``B e <= fl(B e)``
        plus its own rounding; each rounding is at most ``c * magnitude + floor``.
        The values are not clipped to 1 here (the radius bounds them as computed).
        """
        where = self.states
        if k < self.r:
            value[where] = radius[where] = 0.0
            return
        before, spread = self.history[k % self.r]
        found = np.asarray(self.block @ before, dtype=np.float64)
        carried = np.asarray(self.block @ spread, dtype=np.float64)
        carried *= self.weights[1]
        found_part = found * self.weights[0]
        carried += found_part
        carried += self.floor
        value[where] = found
        radius[where] = carried

    def remember(self, k: int, value: FloatArray, radius: FloatArray) -> None:
        slot = self.history[k % self.r]
        # mode="clip": with the default, numpy buffers *out* (the indices are valid).
        np.take(value, self.successors, out=slot[0], mode="clip")
        np.take(radius, self.successors, out=slot[1], mode="clip")


@dataclass(frozen=True, slots=True)
class _RadiusClosure:
    """The zero-reward closure of a level and its forward-error radius.

    ``G(y) = D^-1 (P_out v_out + P' y)``: ``D`` the probabilities of leaving each
    zero-reward state (self-loops divided out), ``P'`` the moves between them.
    """

    #: The zero-reward states, as a slice where they are contiguous.
    zero: slice | IntArray
    #: Columns the zero-reward rows use (the zero-reward states among them).
    used: IntArray
    #: Where the zero-reward states are in *used*.
    local: IntArray
    #: The rows without their self-loops over *used*, and rigorous bounds of ``D``.
    shape: certify.AffineMap
    #: Rounding-bound constants of ``shape.rows`` (see :class:`_RadiusGroup`).
    coefficient: FloatArray
    floor: FloatArray
    #: Certified upper bound of ``tau = A^-1 D 1`` (:func:`_expected_moves`), and its max.
    tau: FloatArray
    tau_max: float

    @classmethod
    def of(cls, levels: Levels) -> _RadiusClosure | None:
        """The closure, or None if ``tau`` is not certified finite (a stiff closure)."""
        assert levels.closure is not None
        used = distinct(np.concatenate([levels.zero_rows.indices, levels.zero]))
        local = np.searchsorted(used, levels.zero)
        empty = np.zeros(used.size)
        shape = certify.AffineMap.of(sp.csr_matrix(levels.zero_rows[:, used]), local,
                                     empty, empty, None)
        tau = _expected_moves(shape, levels.closure)
        if not np.all(np.isfinite(tau)):
            return None
        return cls(_as_slice(levels.zero), used, local, shape,
                   certify.error_coefficient(shape.terms),
                   shape.terms * _FLOOR + _FLOOR, tau, float(tau.max(initial=1.0)))

    def close(self, levels: Levels, value: FloatArray, radius: FloatArray) -> None:
        """Solve the closure into ``value[zero]`` and bound its error in ``radius[zero]``."""
        assert levels.closure is not None
        local = self.local
        values = value[self.used]
        values[local] = 0.0
        right = np.asarray(self.shape.rows @ values, dtype=np.float64)
        values[local] = solved = _solve(levels.closure, right, refine=False)
        defect = self._gap(values, solved, both=True)
        if float(defect.max(initial=0.0)) * self.tau_max > (
                _REFINE_AT * max(float(solved.max(initial=0.0)), 2.0**-900)):
            values[local] = solved = _solve(levels.closure, right, refine=True)
            defect = self._gap(values, solved, both=True)
        value[self.zero] = solved
        # The error: at most the fixed point w of w = D^-1 (P_out e_out + D defect + P' w).
        spread = radius[self.used]
        spread[local] = 0.0
        carried = np.asarray(self.shape.rows @ spread, dtype=np.float64)
        offset = (carried + self.coefficient * carried + self.floor) * _UP
        offset = (offset + self.shape.leave_upper * defect) * _UP
        spread[local] = bound = _solve(levels.closure, offset, refine=False, clip=False)
        overshoot = self._gap(spread, bound, both=False, extra=defect)
        radius[self.zero] = (bound + float(overshoot.max(initial=0.0)) * self.tau) * _UP

    def _gap(self, known: FloatArray, solved: FloatArray, *, both: bool,
             extra: FloatArray | None = None) -> FloatArray:
        """A rigorous bound of ``G(y) - y`` (and of ``y - G(y)`` if *both*), per state.

        *known* holds the other states' values and *y* = *solved* at ``local``;
        *extra* (already an upper bound) is added to ``G``.
        """
        F = self.shape
        numerator = np.asarray(F.rows @ known, dtype=np.float64)
        error = (self.coefficient * numerator + self.floor) * _UP
        with np.errstate(divide="ignore", invalid="ignore"):
            high = (numerator + error) * _UP / F.leave_lower * _UP
            if extra is not None:
                high = (high + extra) * _UP
            gap = high - solved
            if both:
                low = np.maximum(numerator - error, 0.0) / _UP / F.leave_upper / _UP
                gap = np.maximum(gap, solved - low)
        gap = np.maximum(gap, 0.0) * _UP + _FLOOR
        return np.where(np.isnan(gap), np.inf, gap)


def _solve(closure: linalg.Factorization, right: FloatArray, *, refine: bool,
           clip: bool = True) -> FloatArray:
    """``A^-1 right`` by one substitution with the factors (or refined); in [0, 1] if *clip*."""
    solved = None if refine else closure.correction(right)
    if solved is None or not np.all(np.isfinite(solved)):
        solved = closure.solve(np.asarray(right, dtype=np.longdouble))
    return np.clip(solved, 0.0, 1.0) if clip else np.maximum(solved, 0.0)


def _expected_moves(shape: certify.AffineMap, closure: linalg.Factorization) -> FloatArray:
    """A certified upper bound of ``tau = 1 + D^-1 P' tau`` (inf where none was found).

    ``tau = A^-1 D 1`` (``A = D - P'``) is the expected number of moves inside the
    closure. With the offset ``leave_upper >= D``, ``shape.upper(u) <= u`` implies
    ``1 + D^-1 P' u <= u``, hence ``tau <= u`` (the map is monotone and its iterates
    from *u* decrease to its unique fixed point).
    """
    F = replace(shape, offset=shape.leave_upper)
    guess = _solve(closure, shape.leave_upper, refine=False, clip=False)
    trivial = np.full(shape.states.size, np.inf)
    return certify.certify_side(F, np.maximum(guess, 1.0), closure.correction, trivial,
                                up=True)


def _minimal_rewards(P: CsrMatrix, moving: BoolArray, target: BoolArray,
                     rewards: IntArray) -> FloatArray:
    """Per state, a lower bound of the least total reward of a path to *target* through
    *moving* states (the entering step counted), ``inf`` where there is none.

    One multi-source Dijkstra search backwards from the targets, a move out of state
    *s* costing ``rewards[s] + eps`` with ``eps = 1 / (4 n)`` (csgraph needs positive
    weights): a shortest path is simple, so its length is below ``R + 1/4`` for the
    least reward *R* and, rounding included, its floor is at most *R*.
    """
    n = P.shape[0]
    if not target.any():
        return np.full(n, np.inf)
    coo = sp.csr_matrix(P[moving]).tocoo()
    sources = np.flatnonzero(moving)[coo.row]
    keep = coo.data > 0
    weight = rewards[sources[keep]].astype(np.float64) + 1.0 / (4 * n)
    backwards = sp.csr_matrix((weight, (coo.col[keep], sources[keep])), shape=(n, n))
    found = csgraph.dijkstra(backwards, directed=True, indices=np.flatnonzero(target),
                             min_only=True)
    return np.floor(np.asarray(found, dtype=np.float64))
