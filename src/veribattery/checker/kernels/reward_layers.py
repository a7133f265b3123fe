"""A model's product with the reward left to spend or still to gather.

A reward bound on reachability (Storm's ``F^{rew{"r"}<=T} phi`` and
``F^{rew{"r"}>=B} phi``) becomes plain reachability on a product whose state is a
model state and a *layer*: a count of reward units. Every row of the model (a
state's, or a choice's on an MDP) is copied once per layer, and an entry whose
step costs ``c`` leads from layer ``k`` to layer ``k - c`` of its successor:

* **spend** (an upper bound T; layers ``0..T``, the budget left): where ``k - c`` is
  negative the entry leads to one absorbing *spent* state instead, numbered last;
* **gather** (a lower bound B; layers ``0..B``, the reward still needed): the layer
  stops at 0 (``max(0, k - c)``), so layer 0 is the model itself and the bound is
  met there.

A state is numbered ``k * n + s``. Both the DTMC and the MDP checks build on this
(:mod:`~veribattery.checker.kernels.reward_bounded`,
:mod:`~veribattery.checker.mdp.reward_bounded`); rows are kept in layer-major order,
so an MDP's row groups follow from its own.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, IntArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.kernels.reward_epochs import RewardEpochs
from veribattery.checker.kernels.until import until_probs
from veribattery.errors import CheckError, Span

if TYPE_CHECKING:
    from veribattery.checker.workspace import Workspace

__all__ = ["EPOCH_LIMIT", "PRODUCT_LIMIT", "LayeredSets", "gathered_until_bounds",
           "layered_data", "layered_groups", "layered_rows", "product_built",
           "require_product_size"]

#: The most transitions a product may have (about 20 bytes each while it is solved,
#: several times over: some 2 GB at the limit).
PRODUCT_LIMIT = 20_000_000


#: Past :data:`PRODUCT_LIMIT`, at most this many layers are solved one at a time
#: (:mod:`.reward_epochs`: two certified solves a layer, milliseconds on a small model).
EPOCH_LIMIT = 10_000


def product_built(transitions: int, top: int, bound: int, span: Span) -> bool:
    """Whether layers ``0..top`` of a model of *transitions* are built as one product
    (True) or solved one at a time, past :data:`PRODUCT_LIMIT` (False).

    :raises CheckError: too many layers for either, naming the bound and both limits.
    """
    size = (int(top) + 1) * int(transitions)  # (ints: --exact's bounds are gmpy2's)
    if size <= PRODUCT_LIMIT:
        return True
    if top + 1 <= EPOCH_LIMIT:
        return False
    raise CheckError(f"a reward bound of {bound} makes a product of {size:,} transitions on "
                     f"this model (at most {PRODUCT_LIMIT:,}) and {int(top) + 1:,} layers to "
                     f"solve one at a time (at most {EPOCH_LIMIT:,}): use a smaller bound",
                     span)


def require_product_size(transitions: int, top: int, bound: int, span: Span) -> None:
    """Refuse a product of layers ``0..top`` of a model of *transitions* past the limit
    (exact arithmetic builds the product whatever its size).

    :raises CheckError: naming the bound and the product's size.
    """
    size = (int(top) + 1) * int(transitions)  # (ints: --exact's bounds are gmpy2's)
    if size > PRODUCT_LIMIT:
        raise CheckError(f"a reward bound of {bound} makes a product of {size:,} transitions "
                         f"on this model (at most {PRODUCT_LIMIT:,}): use a smaller bound",
                         span)


def gathered_until_bounds(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                          rewards: IntArray, need: int, span: Span, *,
                          workspace: Workspace) -> Bounds:
    """Probability of ``remain U{r}>=need target`` on a DTMC in every state, certified:
    *target* reached through *remain* states once at least *need* of reward is
    gathered, the entering step included (a target met earlier is passed through, if
    it is a *remain* state). Unbounded until on the gather product, from layer *need*;
    past :data:`PRODUCT_LIMIT` transitions, one layer at a time (:mod:`.reward_epochs`).

    :param rewards: the non-negative integer reward of the step leaving each state.
    :raises CheckError: too many layers (:func:`product_built`).
    """
    top = max(need, 0)
    if not product_built(P.nnz, top, need, span):
        monitor = workspace.monitor

        def layer_until(rows: CsrMatrix, passed: BoolArray, reached: BoolArray) -> Bounds:
            with monitor.listening(None):  # (the listener hears the layers, not each solve)
                return until_probs(rows, passed, reached, workspace=workspace)

        epochs = RewardEpochs(P, rewards, remain, target, gather=True)
        return epochs.bounds(top, layer_until, monitor)
    product = layered_rows(P, rewards, top, gather=True)
    sets = LayeredSets.of(remain, target, top, gather=True)
    found = until_probs(product, sets.remain, sets.target, workspace=workspace)
    return found.at(sets.answer)


@dataclass(frozen=True, slots=True)
class LayeredSets:
    """A reward-bounded until's state sets on the product of :func:`layered_rows`.

    :param remain: the product states that may be passed through (a *remain* state on
        any layer; not *spent*).
    :param target: the product states that meet the bound: a *target* state on any
        layer (budget left), or on layer 0 only (*gather*: nothing more needed).
    :param answer: per model state, its product state with the whole bound ahead
        (layer *top*).
    """

    remain: BoolArray
    target: BoolArray
    answer: IntArray

    @classmethod
    def of(cls, remain: BoolArray, target: BoolArray, top: int, *, gather: bool
           ) -> LayeredSets:
        """The sets for a model's *remain* and *target* states, layers ``0..top``."""
        n = target.size
        if gather:
            laid_target = np.concatenate([target, np.zeros(top * n, dtype=bool)])
            laid_remain = np.tile(remain, top + 1)
        else:
            laid_target = np.concatenate([np.tile(target, top + 1), [False]])
            laid_remain = np.concatenate([np.tile(remain, top + 1), [False]])
        return cls(laid_remain, laid_target, np.arange(top * n, (top + 1) * n))


def layered_rows(matrix: CsrMatrix, costs: IntArray, top: int, *, gather: bool
                 ) -> CsrMatrix:
    """The rows of *matrix* (columns: its *n* states) copied for layers ``0..top``.

    :param costs: each row's integer cost (non-negative).
    :param gather: the layer counts reward still needed (stops at 0), not budget left
        (a negative budget leads to the *spent* state, which gets the last row).
    :return: ``(top + 1) * rows`` rows, and one more for *spent* unless *gather*; as
        many columns as rows have states: ``(top + 1) * n``, plus *spent*.
    """
    matrix = sp.csr_matrix(matrix)
    n = matrix.shape[1]
    entry_cost = np.repeat(np.asarray(costs, dtype=np.int64), np.diff(matrix.indptr))
    spent = (top + 1) * n
    columns = []
    for layer in range(top + 1):
        left = layer - entry_cost
        if gather:
            columns.append(np.maximum(left, 0) * n + matrix.indices)
        else:
            columns.append(np.where(left >= 0, left * n + matrix.indices, spent))
    layers = np.arange(top + 1, dtype=np.int64)[:, None]
    entries = (top + 1) * matrix.nnz
    indptr = (layers * matrix.nnz + matrix.indptr[:-1]).ravel()
    if gather:
        shape = ((top + 1) * matrix.shape[0], spent)
        indptr = np.concatenate([indptr, [entries]])
    else:
        shape = ((top + 1) * matrix.shape[0] + 1, spent + 1)
        columns.append(np.array([spent], dtype=np.int64))
        indptr = np.concatenate([indptr, [entries, entries + 1]])
    data = layered_data(matrix.data, top, gather=gather, one=1.0)
    return sp.csr_matrix((data, np.concatenate(columns).astype(np.int64), indptr), shape=shape)


def layered_data(data: np.ndarray, top: int, *, gather: bool, one: object) -> np.ndarray:
    """The entries of :func:`layered_rows` in its order, from the model's entries *data*
    (floats, or exact rationals: the product keeps every entry's value): one copy per
    layer, then *one* for *spent*'s loop unless *gather*."""
    laid = np.tile(data, top + 1)
    return laid if gather else np.concatenate([laid, np.array([one], dtype=data.dtype)])


def layered_groups(groups: IntArray, top: int, *, gather: bool) -> IntArray:
    """An MDP's row groups (``groups[s]..groups[s+1]`` are state *s*'s choices) for
    :func:`layered_rows` of its choices: layer-major, with *spent*'s one row last
    unless *gather*."""
    rows = int(groups[-1])
    layers = np.arange(top + 1, dtype=np.int64)[:, None]
    laid = (layers * rows + np.asarray(groups[:-1], dtype=np.int64)).ravel()
    ends = [(top + 1) * rows] if gather else [(top + 1) * rows, (top + 1) * rows + 1]
    return np.concatenate([laid, ends]).astype(np.int64)
