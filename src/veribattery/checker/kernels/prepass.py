"""The qualitative pre-pass of unbounded properties: graph searches for the states with
probability exactly 0 (:func:`prob0`) or 1 (:func:`prob1`), memoised per sparsity
pattern, and the unknowns of the linear systems that remain (built ahead of time by
:func:`prepare_reach` and :func:`prepare_untils`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._types import BoolArray, CsrMatrix, FloatArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.kernels import systems
from veribattery.checker.kernels.systems import (
    _mask_key,
    _memoised_mask,
    _system,
)

if TYPE_CHECKING:
    from veribattery.checker.workspace import Workspace


def prepare_reach(P: CsrMatrix, target: BoolArray, *, workspace: Workspace) -> BoolArray:
    """Build (and keep in *workspace*) the system of ``R=? [ F target ]`` now, so that
    queries checked before it can be solved on it; returns its unknowns (empty: nothing
    to solve)."""
    maybe = reach_unknowns(P, target, workspace=workspace)
    if maybe.any():
        _system(P, maybe, workspace=workspace)
    return maybe


def prepare_untils(P: CsrMatrix, untils: list[tuple[BoolArray, BoolArray]], *,
                   workspace: Workspace) -> bool:
    """Build (and keep) one system on the union of several untils' unknowns, so that each
    is solved on it (as a superset, or with pinned rows: docs/numerics.md, "Shared
    systems") instead of on a system of its own -- when that union holds at least
    ``QUICK_MIN_STATES`` unknowns, each until has its ``SUPERSET_SHARE`` of them, and
    the union's matrix is triangular in some order (then it is nonsingular: its
    diagonal, the leaving probabilities, is positive). Returns whether it was kept.

    :param untils: ``(remain, target)`` of each unbounded until.
    """
    maybes = [m for m in (until_unknowns(P, *until, workspace=workspace)[0]
                          for until in untils) if m.any()]
    if len(maybes) < 2:
        return False
    union = np.logical_or.reduce(maybes)
    size = int(np.count_nonzero(union))
    if size < systems.QUICK_MIN_STATES or any(np.count_nonzero(m) < systems.SUPERSET_SHARE * size
                                      for m in maybes):
        return False
    system = _system(P, union, workspace=workspace)
    if system.factorization.triangular:
        return True
    workspace.kernels.of(P).systems.pop(_mask_key(union), None)  # not worth keeping
    return False


def until_unknowns(P: CsrMatrix, remain: BoolArray, target: BoolArray, *,
                   workspace: Workspace) -> tuple[BoolArray, BoolArray]:
    """The unknowns of ``remain U target`` and the states whose exact values satisfy its
    equations (``remain & !target``), from the memoised pre-pass."""
    no = prob0(P, remain, target, workspace=workspace)
    yes = prob1(P, remain, target, no, workspace=workspace)
    return ~(no | yes), remain & ~target


def reach_unknowns(P: CsrMatrix, target: BoolArray, *, workspace: Workspace) -> BoolArray:
    """The states of ``R=? [ F target ]``'s linear system: target almost sure, not in it."""
    everywhere = np.ones(P.shape[0], dtype=bool)
    no = prob0(P, everywhere, target, workspace=workspace)
    sure = prob1(P, everywhere, target, no, workspace=workspace)
    return sure & ~target


def reward_free_zeros(P: CsrMatrix, rewards: FloatArray, found: Bounds, *,
                      workspace: Workspace) -> Bounds:
    """*found* (an expected reward, certified) made exactly 0 in the states from which
    no state with a nonzero reward (per step) can be reached: the expectation there is
    a sum of zeros wherever it is finite, where a solver's bounds leave room either side
    of 0 (``0 +- 2e-270`` on a model whose rewards are all 0; PRISM and Storm print 0).

    Only where an interval is finite and holds 0 but is not exactly 0: elsewhere the
    answer is already exact, infinite or undefined, and no search is made."""
    loose = np.isfinite(found.upper) & (found.lower <= 0.0) & (found.upper > 0.0)
    loose |= np.isfinite(found.lower) & (found.lower < 0.0) & (found.upper >= 0.0)
    if not loose.any():
        return found
    everywhere = np.ones(P.shape[0], dtype=bool)
    zero = loose & ~_backward_reach(P, everywhere, rewards != 0, workspace)
    if not zero.any():
        return found
    return Bounds(np.where(zero, 0.0, found.value), np.where(zero, 0.0, found.lower),
                  np.where(zero, 0.0, found.upper))


# ---------------------------------------------------------------------------
# Qualitative pre-pass: graph searches
# ---------------------------------------------------------------------------


def _backward_reach(P: CsrMatrix, through: BoolArray, seeds: BoolArray,
                    workspace: Workspace) -> BoolArray:
    """States with a path to *seeds* whose states before the last lie in *through*.

    One breadth-first search over the reversed graph from a virtual source joined to
    every seed, O(n + m) in C whatever the depth of the chain. Only the states of
    *seeds* or *through* are expanded (their predecessors kept); a state outside both
    may be reached as a leaf, so the answer is the reached states among those two (a
    reached state of *through* was entered from an expanded, truly reached state).
    """
    n = P.shape[0]
    if not seeds.any():
        return np.zeros(n, dtype=bool)
    indptr, indices = _reversed(P, workspace)
    expand = seeds | through
    lengths = np.diff(indptr)
    kept = indices[np.repeat(expand, lengths)]
    seed_idx = np.flatnonzero(seeds).astype(kept.dtype)
    pointer = np.zeros(n + 2, dtype=indptr.dtype)  # csgraph's own index type: no copy
    np.cumsum(np.where(expand, lengths, 0), out=pointer[1 : n + 1])
    pointer[n + 1] = pointer[n] + seed_idx.size
    graph = sp.csr_matrix((np.ones(pointer[-1]), np.concatenate([kept, seed_idx]), pointer),
                          shape=(n + 1, n + 1))
    order = csgraph.breadth_first_order(graph, n, directed=True, return_predecessors=False)
    reached = np.zeros(n + 1, dtype=bool)
    reached[order] = True
    return reached[:n] & expand


def _reversed(P: CsrMatrix, workspace: Workspace
              ) -> tuple[npt.NDArray[np.integer], npt.NDArray[np.integer]]:
    """The predecessors of every state along positive entries (CSR of the transposed
    pattern), built once per matrix."""
    memo = workspace.kernels.of(P)
    if memo.reversed is None:
        pattern = sp.csr_matrix((np.asarray(P.data > 0, dtype=np.int8), P.indices, P.indptr),
                                shape=P.shape)  # shares P's index arrays: not edited
        by_column = pattern.tocsc()  # new arrays: column j lists the i with P[i, j] stored
        by_column.eliminate_zeros()  # then only the positive ones
        memo.reversed = (_narrow(by_column.indptr), by_column.indices)
    return memo.reversed


def _narrow(indptr: npt.NDArray[np.integer]) -> npt.NDArray[np.integer]:
    """*indptr* as int32 when its last entry (and a seed per state more) fits, as
    scipy's graph searches index with int32; int64 otherwise."""
    fits = int(indptr[-1]) + indptr.size < np.iinfo(np.int32).max
    return indptr.astype(np.int32 if fits else np.int64, copy=False)


def prob0(P: CsrMatrix, remain: BoolArray, target: BoolArray, *,
          workspace: Workspace) -> BoolArray:
    """States where ``remain U target`` holds with probability exactly 0.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :param workspace: where the answer is memoised (by *P*'s pattern).
    :return: mask of the states that cannot reach *target* inside *remain*.
    """
    return _memoised_mask(P, "prob0", remain, target,
                          lambda: ~_backward_reach(P, remain & ~target, target, workspace),
                          workspace)


def prob1(P: CsrMatrix, remain: BoolArray, target: BoolArray, no: BoolArray, *,
          workspace: Workspace) -> BoolArray:
    """States where ``remain U target`` holds with probability exactly 1.

    In a finite DTMC the probability is below 1 exactly when a ``remain & !target``
    path leads to a probability-0 state, so this is the complement of one more
    backward search.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :param no: the result of :func:`prob0` for the same arguments.
    :param workspace: where the answer is memoised (by *P*'s pattern).
    :return: mask of the states that reach *target* inside *remain* almost surely.
    """
    through = remain & ~target
    return _memoised_mask(P, "prob1", through, no,
                          lambda: ~_backward_reach(P, through, no, workspace), workspace)
