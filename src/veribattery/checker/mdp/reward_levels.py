"""One layer of a reward bound in one pass, where its cost-free steps have no cycle.

:mod:`~veribattery.checker.kernels.reward_epochs` solves a reward bound one layer at a
time; in a layer, a choice that costs nothing stays in the layer and one that costs
something leaves it with a known (enclosed) value. Where every cycle of the model costs
reward -- time that passes, energy spent -- the cost-free choices among the states that
move (*remain* and not *target*) form no cycle, and a layer's values follow from the
leaves up in one pass, level by level, as the acyclic systems of
:mod:`~veribattery.checker.mdp.acyclic` do: no graph search, no end component, no
policy iteration, and the levels are the same for every layer. The general solve made
each layer a new MDP and ran the qualitative pre-pass on it: on firewire's ``deadline``
(9 levels, 400 layers) 46 s, where Storm takes 4.7 s.

Bounds: each level's rigorous lower images are read at the lower bounds found below
and at the exits' lower ends, its upper images at the upper ones (the images are
monotone, and so is the optimum of them), each row's mass divided by its enclosed sum
as the other passes do (:func:`~veribattery.checker.mdp.system.enclosed_quotients`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker.certify import enclose_product
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.mdp.graph import ChoiceGraph, can_reach
from veribattery.checker.mdp.system import Objective, enclosed_quotients

__all__ = ["LevelledLayers"]


class LevelledLayers:
    """The one-pass solve of a layer's ``remain U target`` (a ``LayerPass`` of
    :class:`~veribattery.checker.kernels.reward_epochs.RewardEpochs`), or None where the
    cost-free choices of the moving states have a cycle.

    :param transitions: the model's choices over its states.
    :param groups: the choices of each state (``row_groups``).
    :param costs: each choice's step reward; those of 0 stay in their layer.
    :param remain: the states the until passes through ...
    :param target: ... and those it reaches (on layer 0 of a gathering bound): a state
        with no path to them through *remain* is 0 on every layer, and not solved (a
        failure state's loop would otherwise be a cost-free cycle).
    """

    __slots__ = ("_costs", "_groups", "_hopeful", "_kept", "_objective", "_transitions")

    def __init__(self, transitions: CsrMatrix, groups: IntArray, costs: IntArray,
                 objective: Objective, remain: BoolArray, target: BoolArray) -> None:
        self._transitions, self._groups, self._costs = transitions, groups, costs
        self._objective: Objective = objective
        owner = np.repeat(np.arange(groups.size - 1, dtype=np.int64), np.diff(groups))
        self._hopeful = can_reach(ChoiceGraph.of(transitions, owner), remain, target)
        # (the levels of the last two moving sets: a gathering bound's layer 0 has its own)
        self._kept: list[tuple[BoolArray, tuple[_Level, ...] | None]] = []

    def __call__(self, remain: BoolArray, target: BoolArray, row_low: FloatArray,
                 row_high: FloatArray) -> Bounds | None:
        """The layer's bounds per state, its leaving rows leading to values within
        ``[row_low, row_high]`` (per row of the model; unread where a row stays)."""
        levels = self._levels(remain & ~target & self._hopeful)
        if levels is None:
            return None
        low = target.astype(np.float64)
        high = low.copy()
        reduce = np.maximum if self._objective == "max" else np.minimum
        for level in levels:
            below, above = level.images(low, high, row_low, row_high)
            low[level.states] = level.optimum(below, reduce)
            high[level.states] = np.minimum(level.optimum(above, reduce), 1.0)
        return Bounds.around(0.5 * low + 0.5 * high, low, high)

    def _levels(self, moving: BoolArray) -> tuple[_Level, ...] | None:
        for kept, levels in self._kept:
            if np.array_equal(kept, moving):
                return levels
        found = _levels_of(self._transitions, self._groups, self._costs, moving)
        self._kept = [(moving, found), *self._kept[:1]]
        return found


def _levels_of(transitions: CsrMatrix, groups: IntArray, costs: IntArray,
               moving: BoolArray) -> tuple[_Level, ...] | None:
    """The moving states by level (those whose cost-free choices lead only to states
    that do not move first), or None if their cost-free choices make a cycle."""
    n = moving.size
    owner = np.repeat(np.arange(n, dtype=np.int64), np.diff(groups))
    rows = np.flatnonzero((costs == 0) & moving[owner])
    lengths = np.diff(transitions.indptr)[rows]
    source = np.repeat(owner[rows], lengths)
    target = transitions.indices[_entries(transitions.indptr, rows)]
    inside = moving[target]
    source, target = source[inside], target[inside]
    pending = np.bincount(source, minlength=n)
    into = np.argsort(target, kind="stable")  # (the edges by the state they enter)
    first = np.searchsorted(target[into], np.arange(n + 1))
    frontier = np.flatnonzero(moving & (pending == 0))
    levels, placed = [], 0
    while frontier.size:
        levels.append(_Level.of(transitions, groups, costs, frontier))
        placed += frontier.size
        entering = into[_entries(first, frontier)]
        pending -= np.bincount(source[entering], minlength=n)
        touched = np.unique(source[entering])
        frontier = touched[pending[touched] == 0]
    return tuple(levels) if placed == int(moving.sum()) else None


def _entries(starts: IntArray, rows: IntArray) -> IntArray:
    """The positions ``starts[r]:starts[r + 1]`` of every row *r* of *rows*, in order."""
    lengths = starts[rows + 1] - starts[rows]
    offsets = np.repeat(starts[rows] - np.cumsum(lengths) + lengths, lengths)
    return np.asarray(np.arange(int(lengths.sum()), dtype=np.int64) + offsets)


@dataclass(frozen=True, slots=True)
class _Level:
    """The states of one level, most choices first, and their rows laid out choice by
    choice: first every state's first choice, then the second choice of those that have
    two (a prefix of the states), and so on, so that a state's optimum is one
    elementwise maximum (minimum) per choice over contiguous slices, where
    ``reduceat`` over rows grouped by state took most of a layer's time (as
    :class:`~veribattery.checker.mdp.levels.ChoiceLevels` lays out the model's rows).

    :param widths: per rank *j*, how many states have a choice *j*.
    :param rows: the model's rows here.
    :param staying: the positions (here) of the rows that cost nothing ...
    :param block: ... their entries (*pattern*: 1 for each) ...
    :param leave_lower: ... and the enclosure of each one's sum.
    """

    states: IntArray
    widths: tuple[int, ...]
    rows: IntArray
    staying: IntArray
    block: CsrMatrix
    pattern: CsrMatrix
    leave_lower: FloatArray
    leave_upper: FloatArray

    @classmethod
    def of(cls, transitions: CsrMatrix, groups: IntArray, costs: IntArray,
           states: IntArray) -> _Level:
        counts = groups[states + 1] - groups[states]
        by_width = np.argsort(-counts, kind="stable")
        states, counts = states[by_width], counts[by_width]
        widths = tuple(int(w) for w in np.bincount(counts)[::-1].cumsum()[::-1][1:])
        rows = np.concatenate([groups[states[:width]] + rank
                               for rank, width in enumerate(widths)]).astype(np.int64)
        staying = np.flatnonzero(costs[rows] == 0)
        block = sp.csr_matrix(transitions[rows[staying]])
        pattern = sp.csr_matrix((np.ones(block.nnz), block.indices, block.indptr),
                                shape=block.shape)
        _, leave_lower, leave_upper = enclose_product(block, np.ones(block.shape[1]))
        return cls(states, widths, rows, staying, block, pattern, leave_lower, leave_upper)

    def optimum(self, images: FloatArray, reduce: np.ufunc) -> FloatArray:
        """Per state, the best of its rows' *images* (laid out as *rows*)."""
        best = images[: self.widths[0]].copy()
        done = self.widths[0]
        for width in self.widths[1:]:
            reduce(best[:width], images[done:done + width], out=best[:width])
            done += width
        return best

    def images(self, low: FloatArray, high: FloatArray, row_low: FloatArray,
               row_high: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Lower and upper bounds of every row's value: the exits' enclosures, and the
        staying rows' images of the bounds below."""
        below, above = row_low[self.rows], row_high[self.rows]
        if self.staying.size:
            below[self.staying] = self._quotients(low, self.leave_upper, up=False)
            above[self.staying] = self._quotients(high, self.leave_lower, up=True)
        return below, above

    def _quotients(self, bound: FloatArray, leave: FloatArray, *, up: bool) -> FloatArray:
        numerator = np.asarray(self.block @ bound, dtype=np.float64)
        terms = np.asarray(self.pattern @ (bound != 0).astype(np.float64), dtype=np.float64)
        return enclosed_quotients(numerator, terms, leave, up=up)
