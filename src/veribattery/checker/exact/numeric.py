"""The numeric part of the exact checker: path probabilities and rewards on state masks.

State masks in, per-state rationals out (:class:`ExactValues`): unbounded until and
reachability rewards after the 0/1 pre-pass, solved SCC by SCC
(:mod:`~veribattery.checker.exact.solve`) on systems kept in the workspace, and the
step-bounded forms by exact matrix-vector products. Shared by the recursion
(:mod:`~veribattery.checker.exact.pctl`) and Storm's formulas
(:mod:`~veribattery.checker.exact.storm`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gmpy2 import mpq

from veribattery._numbers import nearest_float
from veribattery._types import BoolArray, FloatArray
from veribattery.checker import kernels
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.exact.solve import Prepared, prepare, restrict, row_products, solve
from veribattery.checker.formula.leaves import exact_step_bound, step_interval
from veribattery.checker.workspace import Workspace
from veribattery.errors import CheckError
from veribattery.explore.exact.dtmc import ExactDTMC
from veribattery.explore.exact.rational import ObjectArray, rational
from veribattery.lang.nodes import DoubleLit, Expr, IntLit, TimeBound, TimeInterval, Unary

_ZERO = mpq(0)
_ONE = mpq(1)


@dataclass(frozen=True, slots=True)
class ExactValues:
    """Per-state rationals; *infinite* marks expected rewards that are infinite."""

    values: ObjectArray
    infinite: BoolArray

    @classmethod
    def finite(cls, values: ObjectArray) -> ExactValues:
        """Values none of which is infinite."""
        return cls(np.asarray(values, dtype=object), np.zeros(values.size, dtype=bool))

    def floats(self) -> FloatArray:
        """The nearest doubles (``inf`` where infinite, and beyond the largest double)."""
        result = np.asarray(_TO_FLOAT(self.values), dtype=np.float64).reshape(-1)
        result[self.infinite] = np.inf
        return result

    def enclosure(self) -> Bounds:
        """Certified float bounds of the values.

        A rational's conversion to float64 is within one unit in the last place of it
        (correctly rounded or truncated), so the neighbouring floats enclose it; values
        that a float represents exactly (0, 1, halves, infinities) are their own bounds.
        A finite rational beyond the largest double is ``inf`` in ``[largest double,
        inf]``; a NaN (an undefined conditional value) stands for itself.
        """
        floats = self.floats()
        # Only a rational with a power-of-two denominator can be a double: test those.
        undefined = np.isnan(floats)
        defined = np.flatnonzero(~self.infinite & np.isfinite(floats))
        candidates = defined[_DYADIC(self.values[defined]).astype(bool)]
        represented = self.infinite | undefined
        represented[candidates] = _TO_MPQ(floats[candidates]) == self.values[candidates]
        lower = np.where(represented, floats, np.nextafter(floats, -np.inf))
        upper = np.where(represented, floats, np.nextafter(floats, np.inf))
        return Bounds(floats, lower, upper)


#: Elementwise ``float``/``mpq``/power-of-two-denominator over object arrays (C loops).
_TO_FLOAT = np.frompyfunc(nearest_float, 1, 1)
_TO_MPQ = np.frompyfunc(mpq, 1, 1)
_DYADIC = np.frompyfunc(lambda q: q.denominator.bit_count() == 1, 1, 1)


def exact_literal(expr: Expr) -> mpq:
    """A probability or reward bound, read exactly from its digits."""
    match expr:
        case IntLit(value=value):
            return mpq(value)
        case DoubleLit(value=value, text=text):
            return rational(text) if text else rational(value)
        case Unary(op="-", operand=operand):
            return -exact_literal(operand)
    raise CheckError("expected a numeric constant", expr.span)


def _until(model: ExactDTMC, workspace: Workspace, remain: BoolArray, target: BoolArray,
           bound: TimeBound | TimeInterval | None) -> ObjectArray:
    if bound is None:
        return until_probs(model, workspace, remain, target)
    # U[a,b] (and U=k, U>=k): remain for a steps, then U<=b-a (U, where b is unbounded)
    low, high = step_interval(bound, exact_step_bound)
    zero = indicator(np.zeros_like(target))
    if high is not None and high < low:
        return zero
    later = (until_probs(model, workspace, remain, target) if high is None
             else _within(model, workspace, remain, target, high - low))
    return _power(model, remain, later, zero, low)


def _within(model: ExactDTMC, workspace: Workspace, remain: BoolArray, target: BoolArray,
            steps: int) -> ObjectArray:
    """Exact probability of ``remain U<=steps target``."""
    hit = indicator(target)
    return _power(model, remain & ~target, hit, hit, steps)


def until_probs(model: ExactDTMC, workspace: Workspace, remain: BoolArray,
                target: BoolArray) -> ObjectArray:
    """Exact probability of ``remain U target``: pre-pass, then the SCC-wise solve."""
    P = model.dtmc.transitions
    no = kernels.prob0(P, remain, target, workspace=workspace)
    yes = kernels.prob1(P, remain, target, no, workspace=workspace)
    result = indicator(yes)
    maybe = ~(no | yes)
    if maybe.any():
        rows = np.flatnonzero(maybe)
        b = row_products(P, model.probabilities, rows, indicator(yes))
        result[rows] = solve(prepared_system(model, workspace, maybe), b)
    return result


def prepared_system(model: ExactDTMC, workspace: Workspace, maybe: BoolArray) -> Prepared:
    """The system on *maybe*, prepared once per model, mask and workspace (rewards share
    targets)."""
    kept = workspace.kernels.exact(model.dtmc.transitions)
    key = np.packbits(maybe).tobytes()
    found = kept.get(key)
    if not isinstance(found, Prepared):
        found = prepare(restrict(model.dtmc.transitions, model.probabilities, maybe))
        kept[key] = found
    return found


def _next(model: ExactDTMC, target: BoolArray) -> ObjectArray:
    everything = np.arange(model.dtmc.num_states)
    return row_products(model.dtmc.transitions, model.probabilities, everything,
                        indicator(target))


def _power(model: ExactDTMC, moving: BoolArray, start: ObjectArray, offset: ObjectArray,
           k: int) -> ObjectArray:
    """``k`` steps of ``x <- offset + M x`` (M: the rows of *moving*), stopping at a fixpoint."""
    P, probabilities = model.dtmc.transitions, model.probabilities
    rows = np.flatnonzero(moving)
    x = start.copy()
    for _ in range(k):
        following = offset.copy()
        following[rows] = following[rows] + row_products(P, probabilities, rows, x)
        if np.all(following == x):
            break
        x = following
    return x


def indicator(mask: BoolArray) -> ObjectArray:
    """1 on the states of *mask*, 0 elsewhere, as rationals."""
    result: ObjectArray = np.where(mask, _ONE, _ZERO).astype(object)
    return result


def reach_rewards(model: ExactDTMC, workspace: Workspace, rewards: ObjectArray,
                  target: BoolArray) -> ExactValues:
    """Exact ``R=? [F target]``: infinite where *target* is not almost sure (PRISM)."""
    P = model.dtmc.transitions
    everywhere = np.ones(P.shape[0], dtype=bool)
    no = kernels.prob0(P, everywhere, target, workspace=workspace)
    sure = kernels.prob1(P, everywhere, target, no, workspace=workspace)
    result = indicator(np.zeros_like(target))
    maybe = sure & ~target
    if maybe.any():
        rows = np.flatnonzero(maybe)
        result[rows] = solve(prepared_system(model, workspace, maybe), rewards[rows])
    return ExactValues(result, ~sure)
