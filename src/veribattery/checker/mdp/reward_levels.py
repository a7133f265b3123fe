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

Bounds: the pass runs twice in plain floating point, once with the exits' lower ends
and once with their upper ends, each row's mass divided by its computed sum as the other
passes do (``x = P x / s``). Every operation of a pass is on nonnegative numbers (a
product, a sum, a quotient, a maximum or minimum), so its error is bounded a priori
(Higham, *Accuracy and Stability of Numerical Algorithms*, §3.1): with rows of at most
*t* entries, a level's computed images lie within the factors
``D = (1 - g_t)(1 - u) / (1 + g_(t-1))`` and ``U = (1 + g_t)(1 + u) / (1 - g_(t-1))``
(``g_k = k u / (1 - k u)``) of the exact images of the values read, the optimum keeps
them, and by induction over *L* levels a computed value ``y`` lies in ``[D^L x, U^L x]``
of the exact value ``x`` of its pass; so ``y / U^L`` (the lower pass, rounded down) and
``y / D^L`` (the upper, rounded up) enclose the layer, the exits' ends bounding it by
monotonicity. This holds while no product underflows: checked at the end of each pass
(the smallest positive value times the smallest probability at least ``2^-1000``), a
layer that fails it takes the general solve. An exact 0 stays 0. Per-row enclosures
(:func:`~veribattery.checker.mdp.system.enclosed_quotients`) cost three quarters of the
pass, for bounds some ``L t u`` tighter.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker.certify import step_down, step_up
from veribattery.checker.certify.apriori import (
    UNIT,
    float_above,
    float_below,
    gamma,
    least_positive,
    no_underflow,
)
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.mdp.graph import ChoiceGraph, can_reach, segments
from veribattery.checker.mdp.system import Objective

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

    __slots__ = ("_costs", "_groups", "_hopeful", "_kept", "_objective", "_sets",
                 "_transitions")

    def __init__(self, transitions: CsrMatrix, groups: IntArray, costs: IntArray,
                 objective: Objective, remain: BoolArray, target: BoolArray) -> None:
        self._transitions, self._groups, self._costs = transitions, groups, costs
        self._objective: Objective = objective
        self._sets = (remain, target)
        self._hopeful: BoolArray | None = None  # (made when first asked)
        # (the levels of the last two moving sets: a gathering bound's layer 0 has its own)
        self._kept: list[tuple[BoolArray, _Levels | None]] = []

    def __call__(self, remain: BoolArray, target: BoolArray, row_low: FloatArray,
                 row_high: FloatArray) -> Bounds | None:
        """The layer's bounds per state, its leaving rows leading to values within
        ``[row_low, row_high]`` (per row of the model; unread where a row stays)."""
        levels = self._levels(remain & ~target & self._hopeful_states())
        if levels is None:
            return None
        low, high = self._pass(levels, target, row_low), self._pass(levels, target, row_high)
        if not (levels.normal(low) and levels.normal(high)):
            return None
        low, high = levels.below(low), levels.above(high)
        return Bounds.around(0.5 * low + 0.5 * high, low, high)

    def _pass(self, levels: _Levels, target: BoolArray, exits: FloatArray) -> FloatArray:
        """The computed values of a layer whose leaving rows lead to *exits*."""
        values = target.astype(np.float64)
        reduce = np.maximum if self._objective == "max" else np.minimum
        for level in levels.each:
            values[level.states] = level.optimum(level.images(values, exits), reduce)
        return values

    def passes(self, remain: BoolArray, target: BoolArray) -> bool:
        """Whether a layer of these sets is solved in one pass (no cost-free cycle), but
        for values near underflow."""
        return self._levels(remain & ~target & self._hopeful_states()) is not None

    def _hopeful_states(self) -> BoolArray:
        """The states with a path to the target through *remain*."""
        if self._hopeful is None:
            owner = np.repeat(np.arange(self._groups.size - 1, dtype=np.int64),
                              np.diff(self._groups))
            self._hopeful = can_reach(ChoiceGraph.of(self._transitions, owner), *self._sets)
        return self._hopeful

    def _levels(self, moving: BoolArray) -> _Levels | None:
        for kept, levels in self._kept:
            if np.array_equal(kept, moving):
                return levels
        found = _levels_of(self._transitions, self._groups, self._costs, moving)
        self._kept = [(moving, found), *self._kept[:1]]
        return found


def _levels_of(transitions: CsrMatrix, groups: IntArray, costs: IntArray,
               moving: BoolArray) -> _Levels | None:
    """The moving states by level (those whose cost-free choices lead only to states
    that do not move first), or None if their cost-free choices make a cycle."""
    n = moving.size
    owner = np.repeat(np.arange(n, dtype=np.int64), np.diff(groups))
    rows = np.flatnonzero((costs == 0) & moving[owner])
    lengths = np.diff(transitions.indptr)[rows]
    source = np.repeat(owner[rows], lengths)
    target = transitions.indices[segments(transitions.indptr, rows)]
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
        entering = into[segments(first, frontier)]
        pending -= np.bincount(source[entering], minlength=n)
        touched = np.unique(source[entering])
        frontier = touched[pending[touched] == 0]
    return _Levels.of(tuple(levels)) if placed == int(moving.sum()) else None


@dataclass(frozen=True, slots=True)
class _Levels:
    """The levels of the moving states, and what turns a pass's computed values into
    bounds (see the module's docstring).

    :param shrink: ``1 / U^L`` rounded down ...
    :param stretch: ... and ``1 / D^L`` rounded up.
    :param smallest: the smallest positive probability the passes multiply by.
    """

    each: tuple[_Level, ...]
    moving: IntArray
    shrink: float
    stretch: float
    smallest: float

    @classmethod
    def of(cls, each: tuple[_Level, ...]) -> _Levels:
        terms = max((int(np.diff(level.block.indptr).max(initial=1)) for level in each),
                    default=1)
        down, up = _error_factors(terms)
        depth = len(each)
        shrink, stretch = 1 / up**depth, 1 / down**depth
        smallest = min((least_positive(level.block.data) for level in each),
                       default=np.inf)
        return cls(each, np.concatenate([level.states for level in each]),
                   float_below(shrink), float_above(stretch), smallest)

    def normal(self, values: FloatArray) -> bool:
        """Whether no product of a pass that computed *values* can have underflowed: each
        multiplied a probability by one of them (a 0 either way gives an exact 0)."""
        return no_underflow(values, self.smallest)

    def below(self, values: FloatArray) -> FloatArray:
        """Lower bounds from a pass with the exits' lower ends."""
        bounds = values.copy()
        moving = values[self.moving] * self.shrink
        bounds[self.moving] = np.maximum(step_down(moving), 0.0)
        return bounds

    def above(self, values: FloatArray) -> FloatArray:
        """Upper bounds from a pass with the exits' upper ends (a probability: at most 1)."""
        bounds = values.copy()
        moving = values[self.moving]
        bounds[self.moving] = np.where(moving == 0, 0.0,
                                       np.minimum(step_up(moving * self.stretch), 1.0))
        return bounds


def _error_factors(terms: int) -> tuple[Fraction, Fraction]:
    """``D`` and ``U`` of the module's docstring for rows of at most *terms* entries."""
    down = (1 - gamma(terms)) * (1 - UNIT) / (1 + gamma(terms - 1))
    up = (1 + gamma(terms)) * (1 + UNIT) / (1 - gamma(terms - 1))
    return down, up


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
    :param block: ... their entries ...
    :param leave: ... and each one's computed sum.
    """

    states: IntArray
    widths: tuple[int, ...]
    rows: IntArray
    staying: IntArray
    block: CsrMatrix
    leave: FloatArray

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
        leave = np.asarray(block @ np.ones(block.shape[1]), dtype=np.float64)
        return cls(states, widths, rows, staying, block, leave)

    def optimum(self, images: FloatArray, reduce: np.ufunc) -> FloatArray:
        """Per state, the best of its rows' *images* (laid out as *rows*)."""
        best = images[: self.widths[0]].copy()
        done = self.widths[0]
        for width in self.widths[1:]:
            reduce(best[:width], images[done:done + width], out=best[:width])
            done += width
        return best

    def images(self, values: FloatArray, exits: FloatArray) -> FloatArray:
        """Every row's computed value: an exit's from *exits* (per row of the model), a
        staying row's its mass's share of *values* (``P x / s``)."""
        images = exits[self.rows]
        if self.staying.size:
            images[self.staying] = (self.block @ values) / self.leave
        return images
