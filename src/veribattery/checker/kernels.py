"""Numeric kernels of the DTMC checker: matrices and masks in, arrays out.

Every kernel takes the row-stochastic CSR transition matrix *P* and boolean
state masks, never formulas (the recursion over formulas lives in
:mod:`veribattery.checker.pctl`). Unbounded properties run the qualitative
pre-pass first (:func:`prob0`, :func:`prob1`, both graph searches in C via
:mod:`scipy.sparse.csgraph`), so the linear systems are only solved on the
states whose value is strictly between the trivial ones, where they are
nonsingular.

The linear systems of :func:`until_probs` and :func:`reach_rewards` are solved
by :func:`veribattery.checker.linsolve.solve`: sparse LU with extended-precision
iterative refinement, accepted when the normwise backward error is at most
1e-10, with an iterative fallback (its module docstring states the rule).

Step-bounded kernels iterate one sparse matrix-vector product per step and stop
early only at an exact fixpoint (the next iterate equal to the current one in
every bit), after which further steps cannot change the result.
"""

from __future__ import annotations

import weakref
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._types import BoolArray, CsrMatrix, FloatArray
from veribattery.checker import linsolve

# ---------------------------------------------------------------------------
# Memo per transition matrix: properties of one model share targets (``F "done"``
# under two reward structures) and hence graph searches and linear systems.
# Matrices are keyed by identity and forgotten with them; they must not be
# modified in place afterwards (a DTMC's never is).
# ---------------------------------------------------------------------------

#: Linear systems kept per matrix (each holds its matrix and direct solver).
SYSTEMS_KEPT = 4


@dataclass(frozen=True, slots=True)
class _System:
    """``I - P_mm``, the rows ``P[maybe, :]`` and the prepared solver."""

    rows: CsrMatrix
    factorization: linsolve.Factorization


@dataclass(slots=True)
class _Memo:
    matrix: weakref.ref[CsrMatrix]
    masks: dict[tuple[str, bytes, bytes], BoolArray] = field(default_factory=dict)
    systems: OrderedDict[bytes, _System] = field(default_factory=OrderedDict)


_MEMOS: dict[int, _Memo] = {}


def _memo(P: CsrMatrix) -> _Memo:
    key = id(P)
    memo = _MEMOS.get(key)
    if memo is None or memo.matrix() is not P:
        memo = _Memo(weakref.ref(P))
        _MEMOS[key] = memo
        weakref.finalize(P, _forget, key, memo)
    return memo


def _forget(key: int, memo: _Memo) -> None:
    if _MEMOS.get(key) is memo:
        del _MEMOS[key]


def _mask_key(mask: BoolArray) -> bytes:
    return np.packbits(mask).tobytes() + mask.size.to_bytes(8, "little")


def _memoised_mask(P: CsrMatrix, kind: str, a: BoolArray, b: BoolArray,
                   compute: Callable[[], BoolArray]) -> BoolArray:
    masks = _memo(P).masks
    key = (kind, _mask_key(a), _mask_key(b))
    if key not in masks:
        masks[key] = compute()
    return masks[key].copy()


def _system(P: CsrMatrix, maybe: BoolArray) -> _System:
    """The restricted system on *maybe*, built (and its solver prepared) once per matrix."""
    systems = _memo(P).systems
    key = _mask_key(maybe)
    found = systems.get(key)
    if found is None:
        A, rows = linsolve.restricted_matrix(P, maybe)
        found = _System(rows, linsolve.Factorization(A))
        systems[key] = found
        while len(systems) > SYSTEMS_KEPT:
            systems.popitem(last=False)
    else:
        systems.move_to_end(key)
    return found


# ---------------------------------------------------------------------------
# Qualitative pre-pass: graph searches
# ---------------------------------------------------------------------------


def _backward_reach(P: CsrMatrix, through: BoolArray, seeds: BoolArray) -> BoolArray:
    """States with a path to *seeds* whose states before the last lie in *through*.

    One breadth-first search over the reversed graph, from a virtual source
    joined to every seed: O(n + m) in C, whatever the depth of the chain.
    """
    n = P.shape[0]
    if not seeds.any():
        return np.zeros(n, dtype=bool)
    rows = np.repeat(np.arange(n), np.diff(P.indptr))
    # A predecessor is only expanded when it may be passed through.
    keep = (P.data > 0) & through[rows] & ~seeds[rows]
    seed_idx = np.flatnonzero(seeds)
    src = np.concatenate([P.indices[keep], np.full(seed_idx.size, n)])
    dst = np.concatenate([rows[keep], seed_idx])
    graph = sp.csr_matrix((np.ones(src.size), (src, dst)), shape=(n + 1, n + 1))
    order = csgraph.breadth_first_order(graph, n, directed=True, return_predecessors=False)
    reached = np.zeros(n + 1, dtype=bool)
    reached[order] = True
    return reached[:n]


def prob0(P: CsrMatrix, remain: BoolArray, target: BoolArray) -> BoolArray:
    """States where ``remain U target`` holds with probability exactly 0.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :return: mask of the states that cannot reach *target* inside *remain*.
    """
    return _memoised_mask(P, "prob0", remain, target,
                          lambda: ~_backward_reach(P, remain & ~target, target))


def prob1(P: CsrMatrix, remain: BoolArray, target: BoolArray, no: BoolArray) -> BoolArray:
    """States where ``remain U target`` holds with probability exactly 1.

    In a finite DTMC the probability is below 1 exactly when a ``remain & !target``
    path leads to a probability-0 state, so this is the complement of one more
    backward search.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :param no: the result of :func:`prob0` for the same arguments.
    :return: mask of the states that reach *target* inside *remain* almost surely.
    """
    through = remain & ~target
    return _memoised_mask(P, "prob1", through, no, lambda: ~_backward_reach(P, through, no))


# ---------------------------------------------------------------------------
# Unbounded properties: pre-pass, then a linear system (see linsolve)
# ---------------------------------------------------------------------------


def until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray) -> FloatArray:
    """Probability of ``remain U target`` in every state.

    prob0/prob1 fix the states with value 0 and 1; the rest solve
    ``(I - P_mm) x = P_my 1`` under the module's residual rule.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :return: probabilities in [0, 1].
    """
    no = prob0(P, remain, target)
    yes = prob1(P, remain, target, no)
    result = yes.astype(np.float64)
    maybe = ~(no | yes)
    if maybe.any():
        system = _system(P, maybe)
        b = system.rows.astype(np.longdouble) @ yes.astype(np.longdouble)
        result[maybe] = np.clip(system.factorization.solve(b), 0.0, 1.0)
    return result


def reach_rewards(P: CsrMatrix, rewards: FloatArray, target: BoolArray) -> FloatArray:
    """Expected reward accumulated until *target* is first reached (``R=? [F target]``).

    PRISM semantics: 0 in *target* states; infinity in states that reach
    *target* with probability below 1, even where the reward is 0. The reward
    of the step leaving a state is counted; that of the target state is not.

    :param P: row-stochastic CSR transition matrix.
    :param rewards: reward earned per step taken from each state (state + transition).
    :param target: states to reach.
    :return: expected rewards, ``inf`` where *target* is not almost sure.
    """
    everywhere = np.ones(P.shape[0], dtype=bool)
    sure = prob1(P, everywhere, target, prob0(P, everywhere, target))
    result = np.where(sure, 0.0, np.inf)
    maybe = sure & ~target
    if maybe.any():
        # Successors of almost-sure states are almost sure, so the system is closed.
        solver = _system(P, maybe).factorization
        result[maybe] = solver.solve(np.asarray(rewards[maybe], dtype=np.longdouble))
    return result


# ---------------------------------------------------------------------------
# Step-bounded kernels
# ---------------------------------------------------------------------------


def _step_power(M: CsrMatrix, start: FloatArray, offset: FloatArray, k: int) -> FloatArray:
    """``k`` steps of ``x <- offset + M x`` from *start*, stopping at an exact fixpoint."""
    x = start
    for _ in range(k):
        following = offset + M @ x
        if np.array_equal(following, x):
            break
        x = following
    return x


def _rows_in(P: CsrMatrix, mask: BoolArray) -> CsrMatrix:
    """*P* with the rows outside *mask* zeroed (those states stop moving)."""
    return sp.csr_matrix(sp.diags(mask.astype(np.float64), format="csr") @ P)


def next_probs(P: CsrMatrix, target: BoolArray) -> FloatArray:
    """Probability that the next state is in *target* (``X target``).

    :param P: row-stochastic CSR transition matrix.
    :param target: states to reach in one step.
    """
    return np.asarray(P @ target.astype(np.float64), dtype=np.float64)


def bounded_until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                        k: int) -> FloatArray:
    """Probability of reaching *target* within *k* steps while staying in *remain*.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that may be passed through before *target*.
    :param target: states to reach.
    :param k: step bound (``U<=k``), at least 0.
    """
    hit = target.astype(np.float64)
    return _step_power(_rows_in(P, remain & ~target), hit, hit, k)


def lower_bounded_until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                              k: int) -> FloatArray:
    """Probability of ``remain U>=k target``: *remain* for the first *k* steps, then until.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that must hold before *target* is reached.
    :param target: states to reach, at step *k* or later.
    :param k: lower step bound, at least 0.
    """
    later = until_probs(P, remain, target)
    return _step_power(_rows_in(P, remain), later, np.zeros_like(later), k)


def interval_until_probs(P: CsrMatrix, remain: BoolArray, target: BoolArray,
                         low: int, high: int) -> FloatArray:
    """Probability of ``remain U[low,high] target``: *remain* for the first *low* steps,
    then *target* within ``high - low`` more steps, passing through *remain*.

    :param P: row-stochastic CSR transition matrix.
    :param remain: states that must hold before *target* is reached.
    :param target: states to reach, at a step in ``[low, high]``.
    :param low: first step that counts, at least 0.
    :param high: last step that counts, at least *low*.
    """
    later = bounded_until_probs(P, remain, target, high - low)
    return _step_power(_rows_in(P, remain), later, np.zeros_like(later), low)


def cumulative_rewards(P: CsrMatrix, rewards: FloatArray, k: int) -> FloatArray:
    """Expected reward of the first *k* steps (``C<=k``).

    :param P: row-stochastic CSR transition matrix.
    :param rewards: reward earned per step taken from each state (state + transition).
    :param k: number of steps, at least 0.
    """
    offset = np.asarray(rewards, dtype=np.float64)
    return _step_power(P, np.zeros_like(offset), offset, k)


def instantaneous_rewards(P: CsrMatrix, state_rewards: FloatArray, k: int) -> FloatArray:
    """Expected state reward of the state occupied at step *k* (``I=k``).

    :param P: row-stochastic CSR transition matrix.
    :param state_rewards: reward of being in each state.
    :param k: the step, at least 0.
    """
    start = np.asarray(state_rewards, dtype=np.float64)
    return _step_power(P, start, np.zeros_like(start), k)
