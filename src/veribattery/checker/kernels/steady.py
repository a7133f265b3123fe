"""Long-run kernels: bottom strongly connected components, their stationary
distributions, and the probability of ending up in each of them.

``S=? [phi]`` in state *s* is ``sum_B Pr_s(reach B) * pi_B(phi)`` over the BSCCs
*B*; the long-run average reward ``R=? [S]`` replaces ``pi_B(phi)`` by the
expected reward per step under ``pi_B``. The point values of ``pi_B`` come from
one block-diagonal sparse solve (``pi (P_B - I) = 0`` with one equation per BSCC
replaced by ``sum pi = 1``: unique for an irreducible chain, periodic or not, and
equal to the Cesàro long-run average that PRISM reports). Their certified
enclosures come from the renewal theorem (:func:`bscc_averages`), and each
BSCC's value is carried back to the transient states by one certified
absorption system (:func:`~veribattery.checker.kernels.steps.absorption`), so the cost
does not grow with the number of BSCCs.
"""

from __future__ import annotations

import warnings
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.sparse import linalg as spla  # a lazy package in the CLI: read when solving

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker import certify
from veribattery.checker.certify.bounds import Bounds, round_down, round_up
from veribattery.checker.kernels.steps import absorption
from veribattery.checker.kernels.until import reach_rewards

if TYPE_CHECKING:
    from veribattery.checker.workspace import Workspace


@dataclass(frozen=True, slots=True)
class Bsccs:
    """The BSCCs of a DTMC: *component* is each state's BSCC index, -1 if transient."""

    component: IntArray
    count: int

    @property
    def recurrent(self) -> BoolArray:
        """States inside some BSCC."""
        return np.asarray(self.component >= 0)


def _edges(P: CsrMatrix) -> tuple[IntArray, IntArray]:
    """(source, target) of every transition with positive probability."""
    coo = P.tocoo()
    positive = coo.data > 0
    return np.asarray(coo.row[positive]), np.asarray(coo.col[positive])


def bsccs(P: CsrMatrix) -> Bsccs:
    """The bottom strongly connected components of the graph of *P*.

    :param P: row-stochastic CSR transition matrix.
    """
    src, dst = _edges(P)
    graph = sp.csr_matrix((np.ones(src.size), (src, dst)), shape=P.shape)
    count, scc = csgraph.connected_components(graph, directed=True, connection="strong")
    leaves = scc[src] != scc[dst]
    open_scc = np.zeros(count, dtype=bool)
    open_scc[scc[src[leaves]]] = True
    renumber = np.full(count, -1, dtype=np.int64)
    bottom = np.flatnonzero(~open_scc)
    renumber[bottom] = np.arange(bottom.size)
    return Bsccs(renumber[scc], int(bottom.size))


def stationary(P: CsrMatrix, parts: Bsccs) -> FloatArray:
    """Each BSCC's stationary distribution, on its states (0 on transient states).

    One representative state per BSCC gets the unnormalised weight 1; the balance
    equations of the other states then form one sparse nonsingular system (an
    irreducible chain's balance equations have rank n-1), and each BSCC's
    solution is divided by its sum. A representative of tiny stationary mass
    makes the others huge and the solve inaccurate, so the system is solved
    again from each BSCC's heaviest state when that is another one.

    :param P: row-stochastic CSR transition matrix.
    :param parts: the BSCCs of *P*.
    """
    result = np.zeros(P.shape[0])
    states = np.flatnonzero(parts.recurrent)
    comp = parts.component[states]
    inner = sp.csr_matrix(P[states][:, states]).T.tocsr()
    _, first = np.unique(comp, return_index=True)
    weight = _weights(inner, first)
    if not _balanced(inner, weight, comp, parts.count):
        weight = _heaviest_first(inner, weight, comp, parts.count)
    if not np.all(np.isfinite(weight)):
        weight = _averaged(inner, comp, parts.count)
    totals = np.bincount(comp, weights=weight, minlength=parts.count)
    result[states] = weight / totals[comp]
    return result


def _weights(inner: sp.csr_matrix, fixed: IntArray) -> FloatArray:
    """Unnormalised stationary weights with weight 1 in the states *fixed*.

    :param inner: the transposed transition matrix of the BSCC states.
    :param fixed: one state per BSCC.
    """
    m = inner.shape[0]
    weight = np.zeros(m)
    weight[fixed] = 1.0
    rest = np.ones(m, dtype=bool)
    rest[fixed] = False
    if rest.any():
        balance = inner - sp.identity(m, format="csr")
        A = sp.csc_matrix(balance[rest][:, rest])
        b = -np.asarray(inner[rest][:, fixed] @ np.ones(fixed.size)).ravel()
        weight[rest] = np.clip(_solved(A, b), 0.0, None)
    return weight


def _solved(A: sp.spmatrix, b: FloatArray) -> FloatArray:
    """``spsolve(A, b)``; a singular *A* (a probability far below the doubles' precision,
    1e-320 beside 1 - 1e-320 = 1) gives NaN, which the callers test, not a warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", spla.MatrixRankWarning)
        return np.asarray(spla.spsolve(sp.csc_matrix(A), b), dtype=np.float64)


#: Steps averaged by :func:`_averaged`.
_AVERAGED_STEPS = 256


def _averaged(inner: sp.csr_matrix, comp: IntArray, count: int) -> FloatArray:
    """Stationary weights as the Cesàro average of the distributions of the first
    :data:`_AVERAGED_STEPS` steps from the uniform one in each BSCC: the last resort
    when both solves fail. Only the point value and the renewal's reference state
    depend on the weights; the certified bounds do not."""
    x = 1.0 / np.bincount(comp, minlength=count)[comp]
    total = np.zeros_like(x)
    for _ in range(_AVERAGED_STEPS):
        x = np.asarray(inner @ x, dtype=np.float64)
        total += x
    return total / _AVERAGED_STEPS


def _normalised(weight: FloatArray, comp: IntArray, count: int) -> FloatArray:
    totals = np.bincount(comp, weights=weight, minlength=count)
    return np.asarray(weight / np.where(totals > 0, totals, 1.0)[comp])


def _balanced(inner: sp.csr_matrix, weight: FloatArray, comp: IntArray, count: int) -> bool:
    """Whether the normalised weights satisfy ``pi P = pi`` to 1e-12 (absolute)."""
    pi = _normalised(weight, comp, count)
    return bool(np.all(np.isfinite(pi))) and float(np.max(np.abs(inner @ pi - pi))) <= 1e-12


def _heaviest_first(inner: sp.csr_matrix, weight: FloatArray, comp: IntArray,
                    count: int) -> FloatArray:
    """Weights from the normalisation-row system, which needs no good representative.

    Each BSCC's first equation is replaced by ``sum pi = 1`` (a dense row, so the
    factorisation costs more); then the solve is repeated from each BSCC's
    heaviest state, which is well scaled.
    """
    m = inner.shape[0]
    _, first = np.unique(comp, return_index=True)
    keep = np.ones(m)
    keep[first] = 0.0
    normalise = sp.csr_matrix((np.ones(m), (first[comp], np.arange(m))), shape=(m, m))
    A = sp.diags(keep, format="csr") @ (inner - sp.identity(m, format="csr")) + normalise
    b = np.zeros(m)
    b[first] = 1.0
    pi = np.clip(_solved(A, b), 0.0, None)
    order = np.lexsort((-pi, comp))
    heaviest = order[np.searchsorted(comp[order], np.arange(count))]
    better = _weights(inner, np.asarray(heaviest))
    return better if _balanced(inner, better, comp, count) else np.asarray(pi)


class LongRun:
    """The BSCCs and stationary distribution of the last matrix (properties of one model
    share them), held by a :class:`~veribattery.checker.workspace.Workspace`; the
    matrix is held weakly."""

    def __init__(self) -> None:
        self.last: tuple[weakref.ref[CsrMatrix], Bsccs, FloatArray] | None = None

    @property
    def empty(self) -> bool:
        """Whether nothing is kept yet."""
        return self.last is None

    def of(self, P: CsrMatrix) -> tuple[Bsccs, FloatArray]:
        """The BSCCs of *P* and their stationary distributions, kept for the next query."""
        if self.last is not None and self.last[0]() is P:
            return self.last[1], self.last[2]
        parts = bsccs(P)
        pi = stationary(P, parts)
        self.last = (weakref.ref(P), parts, pi)
        return parts, pi


def steady_probs(P: CsrMatrix, target: BoolArray, *, workspace: Workspace) -> Bounds:
    """Long-run probability of being in *target*, from every state (``S=? [target]``),
    certified (:func:`bscc_averages`, then :func:`steps.absorption`).

    :param P: row-stochastic CSR transition matrix.
    :param target: the states counted.
    :param workspace: where the BSCCs and the checker's memos are kept.
    """
    found = _long_run_values(P, target.astype(np.float64), workspace)
    value = np.clip(found.value, 0.0, 1.0)
    return Bounds.around(value, np.maximum(found.lower, 0.0), found.upper)


def long_run_rewards(P: CsrMatrix, rewards: FloatArray, *, workspace: Workspace) -> Bounds:
    """Long-run average reward per step from every state (``R=? [S]``), certified.

    :param P: row-stochastic CSR transition matrix.
    :param rewards: non-negative expected reward per step from each state.
    :param workspace: where the BSCCs and the checker's memos are kept.
    """
    return _long_run_values(P, rewards, workspace)


def _long_run_values(P: CsrMatrix, weights: FloatArray, workspace: Workspace) -> Bounds:
    """Each state's long-run average of *weights*: BSCC averages carried back."""
    parts, pi = workspace.long_run.of(P)
    per_bscc = bscc_averages(P, parts, pi, weights, workspace=workspace)
    comp = np.maximum(parts.component, 0)
    known = Bounds(per_bscc.value[comp], per_bscc.lower[comp], per_bscc.upper[comp])
    return absorption(P, parts.recurrent, known, workspace=workspace)


def bscc_averages(P: CsrMatrix, parts: Bsccs, pi: FloatArray, weights: FloatArray, *,
                  workspace: Workspace) -> Bounds:
    """The average of *weights* under each BSCC's stationary distribution, certified.

    By the renewal theorem the average is ``E[cycle weight] / E[cycle length]`` for
    the cycles from a reference state *r* back to *r*: ``w_r + sum_j P_rj h_j`` over
    ``1 + sum_j P_rj l_j``, with *h* and *l* the expected weight and number of steps
    until *r* (:func:`until.reach_rewards`, certified; one solve for all BSCCs,
    each restricted to itself). Ends are divided with outward rounding. The point
    value is the stationary solve's. BSCCs where *weights* is constant are exact.

    :param parts: the BSCCs of *P*; *pi* their stationary distributions.
    :param weights: non-negative weight per state.
    :param workspace: where the checker's memos are kept.
    """
    states = np.flatnonzero(parts.recurrent)
    comp = parts.component[states]
    value = np.bincount(comp, weights=(pi * weights)[states], minlength=parts.count)
    least = np.full(parts.count, np.inf)
    most = np.full(parts.count, -np.inf)
    np.minimum.at(least, comp, weights[states])
    np.maximum.at(most, comp, weights[states])
    if np.array_equal(least, most):
        return Bounds.exact(least)
    order = np.lexsort((-pi[states], comp))
    ref = order[np.searchsorted(comp[order], np.arange(parts.count))]
    inner = sp.csr_matrix(P[states][:, states])
    low, high = _renewal(inner, ref, weights[states], workspace)
    constant = least == most
    lower, upper = np.where(constant, least, low), np.where(constant, most, high)
    return Bounds.around(np.where(constant, least, value), lower, upper)


def _renewal(inner: CsrMatrix, ref: IntArray, weights: FloatArray,
             workspace: Workspace) -> tuple[FloatArray, FloatArray]:
    """Certified ends of ``E[cycle weight] / E[cycle length]`` from each state *ref*."""
    target = np.zeros(inner.shape[0], dtype=bool)
    target[ref] = True
    rows = sp.csr_matrix(inner[ref])
    gained = reach_rewards(inner, weights, target, workspace=workspace)
    steps = reach_rewards(inner, np.ones(inner.shape[0]), target, workspace=workspace)
    ones = np.ones(ref.size)
    gained_low = certify.enclose_product(rows, gained.lower, weights[ref])[1]
    gained_high = certify.enclose_product(rows, gained.upper, weights[ref])[2]
    steps_low = certify.enclose_product(rows, steps.lower, ones)[1]
    steps_high = certify.enclose_product(rows, steps.upper, ones)[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        low = round_down(np.maximum(gained_low, 0.0) / steps_high)
        high = round_up(gained_high / np.maximum(steps_low, 1.0))
    return np.where(np.isnan(low), 0.0, low), np.where(np.isnan(high), np.inf, high)


def total_rewards(P: CsrMatrix, rewards: FloatArray, *, workspace: Workspace) -> Bounds:
    """Expected total reward along the whole path (``R=? [C]``), certified.

    Every path enters a BSCC almost surely. In a BSCC with some reward, reward
    is earned infinitely often; in one without ("cold"), none is earned any
    more. So the total reward is the reward until a cold BSCC is reached --
    infinite where that is not almost sure -- which is
    :func:`~veribattery.checker.kernels.until.reach_rewards` with its certificate.

    :param P: row-stochastic CSR transition matrix.
    :param rewards: non-negative expected reward per step from each state.
    :param workspace: where the checker's memos are kept.
    """
    parts = bsccs(P)
    recurrent = parts.recurrent
    earning = np.zeros(parts.count, dtype=bool)
    earning[parts.component[recurrent & (rewards > 0)]] = True
    cold = recurrent & ~earning[np.maximum(parts.component, 0)]
    return reach_rewards(P, rewards, cold, workspace=workspace)
