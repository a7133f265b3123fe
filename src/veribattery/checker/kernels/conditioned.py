"""The product chain of a DTMC conditioned on ``F b`` (Doob's h-transform), built explicitly.

The fallback of conditional properties whose objective has a step or reward bound
(:func:`~veribattery.checker.kernels.conditional.conditional_values`): copy 0 of the
states before *b* with their transitions reweighted by ``P(F b)``, copy 1 of the states
after it unchanged, with the model's variables, labels and rewards carried over.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker.kernels.until import until_probs
from veribattery.explore.dtmc import DTMC, RewardVectors

if TYPE_CHECKING:
    from veribattery.checker.workspace import Workspace


@dataclass(frozen=True, slots=True)
class ConditionedChain:
    """The conditioned DTMC of a model given ``F b``, and where each state starts in it.

    :param dtmc: the product chain (copy 0 then copy 1), with the original variables,
        labels and reward structures carried over to each copy.
    :param start: for each original state, its index in *dtmc*, or -1 where
        ``P(F b) = 0``.
    :param origin: for each product state, the original state it copies.
    :param condition: ``P(F b)`` in each original state.
    """

    dtmc: DTMC
    start: IntArray
    origin: IntArray
    condition: FloatArray

    def lift(self, values: FloatArray) -> FloatArray:
        """Values over the product chain → values of the original states (NaN: undefined)."""
        result = np.full(self.start.size, np.nan)
        defined = self.start >= 0
        result[defined] = values[self.start[defined]]
        return result


def conditioned_chain(dtmc: DTMC, condition: BoolArray, *, workspace: Workspace
                      ) -> ConditionedChain:
    """The chain of *dtmc* conditioned on eventually reaching *condition*.

    :param dtmc: the model.
    :param condition: the states *b* of the condition ``F b``.
    :param workspace: where the checker's memos are kept.
    """
    P = dtmc.transitions
    n = dtmc.num_states
    x = until_probs(P, np.ones(n, dtype=bool), condition, workspace=workspace).value
    before = (x > 0) & ~condition
    after = _reachable_from(P, condition)
    origin = np.concatenate([np.flatnonzero(before), np.flatnonzero(after)])
    index0 = _index_map(before)
    index1 = _index_map(after)
    matrix = sp.vstack([_conditioned_rows(P, before, condition, x, index0, index1, origin.size),
                        _shifted_rows(P, after, index1, int(before.sum()), origin.size)])
    start = np.full(n, -1, dtype=np.int64)
    start[before] = index0[before]
    start[condition] = index1[condition] + int(before.sum())
    product = _carry_over(dtmc, sp.csr_matrix(matrix), origin, start)
    return ConditionedChain(product, start, origin, x)


def _reachable_from(P: CsrMatrix, seeds: BoolArray) -> BoolArray:
    """States reachable from *seeds* (the seeds included): one search in C."""
    n = P.shape[0]
    seed_idx = np.flatnonzero(seeds)
    rows = np.repeat(np.arange(n), np.diff(P.indptr))
    keep = P.data > 0
    src = np.concatenate([rows[keep], np.full(seed_idx.size, n)])
    dst = np.concatenate([P.indices[keep], seed_idx])
    graph = sp.csr_matrix((np.ones(src.size), (src, dst)), shape=(n + 1, n + 1))
    order = csgraph.breadth_first_order(graph, n, directed=True, return_predecessors=False)
    reached = np.zeros(n + 1, dtype=bool)
    reached[order] = True
    return reached[:n]


def _index_map(mask: BoolArray) -> IntArray:
    """Position of each masked state among the masked ones; -1 elsewhere."""
    index = np.full(mask.size, -1, dtype=np.int64)
    index[mask] = np.arange(int(mask.sum()))
    return index


def _conditioned_rows(P: CsrMatrix, before: BoolArray, condition: BoolArray, x: FloatArray,
                      index0: IntArray, index1: IntArray, size: int) -> sp.csr_matrix:
    """Copy 0: ``P(s,t) x(t) / x(s)``, into copy 1 where *t* meets the condition."""
    rows = sp.coo_matrix(P[before])
    keep = x[rows.col] > 0
    r, c = rows.row[keep], rows.col[keep]
    weights = rows.data[keep] * x[c]
    columns = np.where(condition[c], index1[c] + int(before.sum()), index0[c])
    # Normalise each row to sum 1 exactly (x solves the system only to rounding).
    sums = np.bincount(r, weights=weights, minlength=int(before.sum()))
    matrix = sp.csr_matrix((weights / sums[r], (r, columns)),
                           shape=(int(before.sum()), size))
    matrix.sum_duplicates()
    return matrix


def _shifted_rows(P: CsrMatrix, after: BoolArray, index1: IntArray, offset: int,
                  size: int) -> sp.csr_matrix:
    """Copy 1: the original rows of the states reachable from the condition."""
    rows = sp.coo_matrix(P[after])
    columns = index1[rows.col] + offset
    return sp.csr_matrix((rows.data, (rows.row, columns)), shape=(int(after.sum()), size))


def _carry_over(dtmc: DTMC, matrix: CsrMatrix, origin: IntArray, start: IntArray) -> DTMC:
    """The product DTMC: each product state has the variables, labels, rewards of its origin."""
    initial = start[dtmc.initial]
    return DTMC(
        transitions=matrix,
        states=dtmc.states[origin],
        variable_names=dtmc.variable_names,
        initial=initial[initial >= 0],
        labels={name: mask[origin] for name, mask in dtmc.labels.items()},
        rewards=tuple(RewardVectors(r.name, r.state[origin], r.transition[origin])
                      for r in dtmc.rewards),
    )
