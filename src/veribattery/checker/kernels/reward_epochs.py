"""A reward-bounded until one layer at a time, for products too large to build.

:mod:`.reward_layers` copies the model once per layer of reward left to spend (or
still to gather) and solves the copies together. Past
:data:`~.reward_layers.PRODUCT_LIMIT` transitions this module solves them one at a
time instead, from layer 0 up, as Storm's epoch-based algorithm does (Hensel,
Junges, Katoen, Quatmann, Volk, TACAS 2018), keeping only the layers a step can still
reach down to.

In layer *k*, a row (a state's, or a choice's) that costs nothing stays in the layer;
one that costs ``c > 0`` leaves it for layer ``k - c`` (spend; a negative budget
fails) or ``max(0, k - c)`` (gather), whose values are known by then. Such a row is
replaced by a step to a *yes* state with the probability ``o`` of its destination
row's value and to a *no* state with ``1 - o``: layer *k* is then plain unbounded
until on the model plus two states, solved by the caller's certified solver.

The known values are intervals, so each layer is solved twice: with every ``o`` at
its certified lower end (the enclosure of the row's product with the lower bounds)
and at its upper end. An until's value rises with the values its exits lead to, for
every strategy and so for the optimum, so the first solve's lower bounds and the
second's upper bounds enclose the layer's values. The intervals widen a little with
each layer (each solve adds its own certificate's width).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker.certify import enclose_product
from veribattery.checker.certify.apriori import NonnegativeProducts, zero_terms_only
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.certify.fixpoint import Progress

__all__ = ["LayerPass", "LayerSolve", "RewardEpochs"]

#: Certified bounds of ``remain U target`` in every state of a layer's rows (over the
#: model's states, then *yes*, then *no*; one row more each for *yes* and *no*).
LayerSolve = Callable[[CsrMatrix, BoolArray, BoolArray], Bounds]
#: The same from the layer's parts, or None where it does not apply: *remain* and
#: *target* over the model's states, and per row of the model the lower and upper ends
#: of the value it leads to if it leaves the layer (unread where it stays).
LayerPass = Callable[[BoolArray, BoolArray, FloatArray, FloatArray], Bounds | None]


@dataclass(frozen=True, slots=True)
class RewardEpochs:
    """A reward-bounded until on a model's rows, layer by layer.

    :param matrix: the model's rows (states', or choices') over its *n* states.
    :param costs: each row's step reward, a non-negative integer.
    :param remain: the states that may be passed through.
    :param target: the states to reach.
    :param gather: a lower bound (the layer counts reward still needed; the target
        counts on layer 0 only), not an upper one (budget left).
    """

    matrix: CsrMatrix
    costs: IntArray
    remain: BoolArray
    target: BoolArray
    gather: bool

    def bounds(self, top: int, solve: LayerSolve, progress: Progress | None = None,
               one_pass: LayerPass | None = None) -> Bounds:
        """Certified bounds of the until from layer *top* (the whole bound ahead), per state.

        :param progress: told ``(layers done, layers, "reward layers")``.
        :param one_pass: tried first on a layer whose rows that cost something leave it
            (not a gathering bound's layer 0), *solve* where it gives None.
        """
        exits = _Exits.of(self.matrix, self.costs)
        known: dict[int, tuple[FloatArray, FloatArray]] = {}
        found = Bounds.exact(np.zeros(self.matrix.shape[1]))
        asked: tuple[FloatArray, FloatArray] | None = None  # the last layer's exit values
        for layer in range(top + 1):
            # (gathering, layer 0 is the model itself: every step stays there)
            within = _Exits.none(self.matrix) if self.gather and layer == 0 else exits
            low, high = within.values(layer, known, gather=self.gather)
            same = (asked is not None and layer > 1 and np.array_equal(low, asked[0])
                    and np.array_equal(high, asked[1]))
            if not same:  # (else the layer is the last one over again: low layers of 0s)
                passed = None if within is not exits or one_pass is None else one_pass(
                    *self._sets(layer, exits=False), *self._per_row(within, low, high))
                found = (passed if passed is not None
                         else self._layer(layer, within, (low, high), solve))
            asked = (low, high)
            known[layer] = (found.lower, found.upper)
            stale = layer - exits.deepest  # (no step reaches further down from the next)
            if stale > 0 or not self.gather:  # (gathering reads layer 0 from every layer)
                known.pop(stale, None)
            if progress is not None:
                progress(layer + 1, top + 1, "reward layers")
        return found

    def _layer(self, layer: int, within: _Exits, leaving: tuple[FloatArray, FloatArray],
               solve: LayerSolve) -> Bounds:
        """The bounds of *layer* whose exits lead to values within *leaving*."""
        n = self.matrix.shape[1]
        (low, high), (remain, target) = leaving, self._sets(layer)
        below = solve(self._rows(within, low), remain, target)
        above = below if np.array_equal(low, high) else solve(self._rows(within, high),
                                                               remain, target)
        middle = 0.5 * below.value[:n] + 0.5 * above.value[:n]
        return Bounds.around(middle, below.lower[:n], above.upper[:n])

    def _sets(self, layer: int, *, exits: bool = True) -> tuple[BoolArray, BoolArray]:
        """The layer's *remain* and *target* states, then (if *exits*) *yes* (a target)
        and *no*."""
        target = self.target if layer == 0 or not self.gather else np.zeros_like(self.target)
        if not exits:
            return self.remain, target
        return (np.concatenate([self.remain, [False, False]]),
                np.concatenate([target, [True, False]]))

    def _per_row(self, exits: _Exits, low: FloatArray, high: FloatArray
                 ) -> tuple[FloatArray, FloatArray]:
        """The exits' values *low* and *high* per row of the model (0 where it stays)."""
        rows = self.matrix.shape[0]
        row_low, row_high = np.zeros(rows), np.zeros(rows)
        row_low[exits.leaving], row_high[exits.leaving] = low, high
        return row_low, row_high

    def _rows(self, exits: _Exits, leaving: FloatArray) -> CsrMatrix:
        """The layer's rows: each row that leaves it, a step to *yes* with its
        probability in *leaving* and to *no* with the rest; then *yes*'s and *no*'s
        loops. (No entry of 0 is stored: an entry is an edge to the graph searches.)"""
        n, rows = self.matrix.shape[1], self.matrix.shape[0]
        staying = exits.staying
        yes, no = leaving > 0, leaving < 1
        row = np.concatenate([staying.row, exits.leaving[yes], exits.leaving[no],
                              [rows, rows + 1]])
        column = np.concatenate([staying.col, np.full(int(yes.sum()), n),
                                 np.full(int(no.sum()), n + 1), [n, n + 1]])
        data = np.concatenate([staying.data, leaving[yes], 1.0 - leaving[no], [1.0, 1.0]])
        return sp.csr_matrix((data, (row, column)), shape=(rows + 2, n + 2))


@dataclass(frozen=True, slots=True)
class _Exits:
    """The rows that cost something, by cost, and their products' matrices.

    :param staying: the entries of the rows that cost nothing (they stay in their
        layer), numbered by the model's rows.
    :param leaving: the others, by cost.
    :param by_cost: per cost, its rows' positions in *leaving* and their products.
    :param deepest: the largest cost (how far below a layer its values are read).
    """

    staying: sp.coo_matrix
    leaving: IntArray
    by_cost: tuple[tuple[int, IntArray, NonnegativeProducts], ...]
    deepest: int

    @classmethod
    def of(cls, matrix: CsrMatrix, costs: IntArray) -> _Exits:
        order = np.argsort(costs, kind="stable")
        leaving = order[costs[order] > 0]
        kinds, starts = np.unique(costs[leaving], return_index=True)
        ends = np.append(starts[1:], leaving.size)
        by_cost = tuple((int(c), np.arange(s, e),
                         NonnegativeProducts.of(sp.csr_matrix(matrix[leaving[s:e]])))
                        for c, s, e in zip(kinds, starts, ends, strict=True))
        return cls(_rows_of(matrix, np.flatnonzero(costs == 0)), leaving, by_cost,
                   int(kinds[-1]) if kinds.size else 0)

    @classmethod
    def none(cls, matrix: CsrMatrix) -> _Exits:
        """Every row of *matrix* staying."""
        return cls(_rows_of(matrix, np.arange(matrix.shape[0])), np.zeros(0, dtype=np.int64),
                   (), 0)

    def values(self, layer: int, known: dict[int, tuple[FloatArray, FloatArray]], *,
               gather: bool) -> tuple[FloatArray, FloatArray]:
        """Per leaving row, certified lower and upper ends of the value it leads to from
        *layer* (the product of its row with the bounds of its destination layer)."""
        low, high = np.zeros(self.leaving.size), np.zeros(self.leaving.size)
        for cost, positions, rows in self.by_cost:
            destination = max(layer - cost, 0) if gather else layer - cost
            if destination < 0:
                continue  # (spent: the until fails)
            lower, upper = known[destination]
            low[positions] = _bounded(rows, lower, up=False)
            high[positions] = _bounded(rows, upper, up=True)
        return np.clip(low, 0.0, 1.0), np.clip(high, 0.0, 1.0)


def _bounded(products: NonnegativeProducts, x: FloatArray, *, up: bool) -> FloatArray:
    """A lower (upper) bound of each row's product with *x*: the a priori one, or the
    per-row enclosure where a product may have underflowed or *x* holds only 0s and 1s
    (its products are exact, and so is a row with one nonzero term). Either keeps a row
    that reads only exact 0s exactly 0: counting its entries as terms that may underflow
    made it ``[0, 2k ETA]``, which grew through the layers (7e-322 +- 8e-322 after
    firewire's 201 layers, where the value is 0, and ``P>0`` on it undecided)."""
    if not bool(np.all((x == 0) | (x == 1))):
        found = products.bound(x, up=up)
        if found is not None:
            return found
    product, below, above = enclose_product(products.matrix, x)
    if not up:
        return below
    return np.asarray(np.where(zero_terms_only(products.matrix, x, product == 0), 0.0, above),
                      dtype=np.float64)


def _rows_of(matrix: CsrMatrix, rows: IntArray) -> sp.coo_matrix:
    """The entries of *matrix*'s *rows*, each numbered by its row in *matrix*."""
    taken = sp.csr_matrix(matrix[rows]).tocoo()
    return sp.coo_matrix((taken.data, (rows[taken.row], taken.col)), shape=matrix.shape)
