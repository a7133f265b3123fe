"""Certified optimal values of a system whose class graph has no cycle, in one pass.

When every component of the class graph is trivial (:attr:`Levels.acyclic`: each
class's rows read only classes of lower levels and known states; a row's mass
that stays in its class is folded into ``s_a``), the optimum of a level is
decided by the levels below it, once. Taking the levels from the known states
back, each level's rigorous lower images are read at the lower bounds found
below and its upper images at the upper bounds: ``G_a`` is monotone, so by
induction over the levels ``lower <= x* <= upper`` -- interval iteration
(:mod:`~veribattery.checker.mdp.certificate`) in topological order, where one
sweep is the fixed point. It replaces policy iteration's LU solves and the
certificate on such systems: the mission MDP (``Pmax``: 475,766 classes in 1,203
levels) is one.

The point values are the same pass in extended precision, rounded to doubles at the
end; the strategy is their greedy one (ties kept on the caller's preferred rows).
Every strategy of an acyclic system reaches the known states, so none is improper.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from veribattery._types import FloatArray, IntArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.certify.fixpoint import Progress
from veribattery.checker.mdp.system import ChoiceSystem, Objective, enclosed_quotients
from veribattery.checker.mdp.topological import LevelOrder, Levels, greedy_rows

__all__ = ["acyclic_optimum"]

LongArray = npt.NDArray[np.longdouble]


def acyclic_optimum(system: ChoiceSystem, objective: Objective, known: FloatArray,
                    offset: FloatArray | None, levels: Levels, preferred: IntArray,
                    ceiling: float, *, progress: Progress | None = None
                    ) -> tuple[Bounds, IntArray]:
    """The certified optimal values of an acyclic *system* and a greedy strategy.

    :param levels: the system's class levels, every component trivial.
    :param preferred: per class, a row kept wherever it ties with the best.
    :param ceiling: an upper bound of every value (1 for probabilities, else ``inf``),
        which the upper bounds are clipped to.
    :param progress: told ``(levels done, levels, "levels")`` after each level.
    :return: the bounds per class, and per class the strategy's row.
    """
    if not levels.acyclic:
        raise ValueError("the class graph has a cycle")
    value, lower, upper = _level_pass(system, objective, known, offset, levels, ceiling,
                                      progress)
    rows = greedy_rows(system.images(value, known, offset), system.groups[:-1], objective,
                       preferred)
    return Bounds.around(value, lower, upper), rows


def _level_pass(system: ChoiceSystem, objective: Objective, known: FloatArray,
                offset: FloatArray | None, levels: Levels, ceiling: float,
                progress: Progress | None) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The point values and the lower and upper bounds of every class, level by level
    (the rows in level order are let go before the caller's greedy strategy)."""
    order = LevelOrder.of(system, offset, levels)
    lower = np.concatenate([np.zeros(system.size), known])
    upper, value = lower.copy(), lower.astype(np.longdouble)
    reduce = np.maximum if objective == "max" else np.minimum
    for k in range(levels.count):
        lo, hi = int(levels.starts[k]), int(levels.starts[k + 1])
        first, last = order.row_range(lo, hi)
        rows = _LevelRows.of(order, first, last)
        starts, classes = order.local_starts(lo, hi), levels.classes[lo:hi]
        value[classes] = reduce.reduceat(rows.extended_images(value), starts)
        lower[classes] = reduce.reduceat(rows.enclosed_images(
            lower, order.per_row(system.leave_upper, first, last), up=False), starts)
        upper[classes] = np.minimum(reduce.reduceat(rows.enclosed_images(
            upper, order.per_row(system.leave_lower, first, last), up=True), starts), ceiling)
        if progress is not None:
            progress(k + 1, levels.count, "levels")
    n = system.size
    with np.errstate(over="ignore"):  # a value beyond the doubles is inf, as its bounds say
        point = value[:n].astype(np.float64)
    return point, lower[:n].copy(), upper[:n].copy()


@dataclass(frozen=True, slots=True)
class _LevelRows:
    """The entries of one level's rows, as plain arrays: a level of the mission MDP has
    a few hundred rows, where a sparse matrix's construction and product cost more than
    the arithmetic. Every row has an entry (it leaves its class).

    :param starts: per row, where its entries begin in *data*.
    """

    data: FloatArray
    columns: IntArray
    starts: IntArray
    rewards: FloatArray | None

    @classmethod
    def of(cls, order: LevelOrder, first: int, last: int) -> _LevelRows:
        block = order.block(first, last)
        rewards = None if order.offset is None else order.per_row(order.offset, first, last)
        return cls(block.data, block.indices, block.indptr[:-1], rewards)

    def extended_images(self, value: LongArray) -> LongArray:
        """``G_a(value)`` in extended precision, ``s_a`` summed there too: a row whose
        entries all lead to the same value gives exactly that value, whatever the
        rounding of its stored probabilities."""
        data = self.data.astype(np.longdouble)
        numerator = np.add.reduceat(data * value[self.columns], self.starts)
        if self.rewards is not None:
            numerator += self.rewards
        return np.asarray(numerator / np.add.reduceat(data, self.starts))

    def enclosed_images(self, bound: FloatArray, leave: FloatArray, *, up: bool) -> FloatArray:
        """Rigorous bounds of ``G_a(bound)`` from above if *up*, else from below (the
        enclosure of ``s_a`` on the side to divide by: *leave*)."""
        read = bound[self.columns]
        numerator = np.add.reduceat(self.data * read, self.starts)
        terms = np.add.reduceat((read != 0).astype(np.float64), self.starts)
        if self.rewards is not None:
            numerator += self.rewards
            terms += self.rewards != 0
        return enclosed_quotients(numerator, terms, leave, up=up)
