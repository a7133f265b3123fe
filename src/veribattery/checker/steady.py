"""Long-run kernels: bottom strongly connected components, their stationary
distributions, and the probability of ending up in each of them.

``S=? [phi]`` in state *s* is ``sum_B Pr_s(reach B) * pi_B(phi)`` over the BSCCs
*B*; the long-run average reward ``R=? [S]`` replaces ``pi_B(phi)`` by the
expected reward per step under ``pi_B``. Rather than one reachability problem per
BSCC, the value of each BSCC is spread over its states and carried back to the
transient states by one linear system (absorption), so the cost does not grow
with the number of BSCCs. Stationary distributions of all BSCCs come from one
block-diagonal sparse solve: ``pi (P_B - I) = 0`` with one equation per BSCC
replaced by ``sum pi = 1`` (unique for an irreducible chain, periodic or not, and
equal to the Cesàro long-run average that PRISM reports).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.sparse.linalg import spsolve

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery.checker import kernels, linsolve


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
        weight[rest] = np.clip(spsolve(A, b), 0.0, None)
    return weight


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
    pi = np.clip(spsolve(sp.csc_matrix(A), b), 0.0, None)
    order = np.lexsort((-pi, comp))
    heaviest = order[np.searchsorted(comp[order], np.arange(count))]
    better = _weights(inner, np.asarray(heaviest))
    return better if _balanced(inner, better, comp, count) else np.asarray(pi)


def absorbed(P: CsrMatrix, parts: Bsccs, per_bscc: FloatArray) -> FloatArray:
    """``sum_B Pr_s(reach B) * per_bscc[B]`` in every state *s*.

    :param P: row-stochastic CSR transition matrix.
    :param parts: the BSCCs of *P*.
    :param per_bscc: one value per BSCC.
    """
    recurrent = parts.recurrent
    result = np.zeros(P.shape[0])
    result[recurrent] = per_bscc[parts.component[recurrent]]
    values = np.unique(per_bscc)
    transient = ~recurrent
    if values.size == 1:
        result[transient] = values[0]
        return result
    if not transient.any():
        return result
    # Transient states that reach no BSCC of nonzero value keep 0.
    nonzero = recurrent & (result != 0)
    zero = kernels.prob0(P, np.ones(P.shape[0], dtype=bool), nonzero)
    maybe = transient & ~zero
    if maybe.any():
        A, rows = linsolve.restricted_matrix(P, maybe)
        b = rows.astype(np.longdouble) @ np.where(recurrent, result, 0.0).astype(np.longdouble)
        result[maybe] = linsolve.Factorization(A).solve(b)
    return result


#: The BSCCs and stationary distribution of the last matrix (properties of one model
#: share them); keyed by identity and dropped with the matrix.
_LAST: list[tuple[weakref.ref[CsrMatrix], Bsccs, FloatArray]] = []


def _long_run(P: CsrMatrix) -> tuple[Bsccs, FloatArray]:
    if _LAST and _LAST[0][0]() is P:
        return _LAST[0][1], _LAST[0][2]
    parts = bsccs(P)
    pi = stationary(P, parts)
    _LAST[:] = [(weakref.ref(P), parts, pi)]
    return parts, pi


def steady_probs(P: CsrMatrix, target: BoolArray) -> FloatArray:
    """Long-run probability of being in *target*, from every state (``S=? [target]``).

    :param P: row-stochastic CSR transition matrix.
    :param target: the states counted.
    """
    parts, pi = _long_run(P)
    recurrent = parts.recurrent
    mass = np.bincount(parts.component[recurrent], weights=(pi * target)[recurrent],
                       minlength=parts.count).astype(np.float64)
    return np.clip(absorbed(P, parts, mass), 0.0, 1.0)


def long_run_rewards(P: CsrMatrix, rewards: FloatArray) -> FloatArray:
    """Long-run average reward per step from every state (``R=? [S]``).

    :param P: row-stochastic CSR transition matrix.
    :param rewards: expected reward per step taken from each state (state + transition).
    """
    parts, pi = _long_run(P)
    recurrent = parts.recurrent
    average = np.bincount(parts.component[recurrent], weights=(pi * rewards)[recurrent],
                          minlength=parts.count).astype(np.float64)
    return absorbed(P, parts, average)


def total_rewards(P: CsrMatrix, rewards: FloatArray) -> FloatArray:
    """Expected total reward along the whole path (``R=? [C]``).

    Infinite in the states that reach, with positive probability, a BSCC in
    which some reward is earned (it is then earned infinitely often); otherwise
    the reward until a BSCC is entered.

    :param P: row-stochastic CSR transition matrix.
    :param rewards: non-negative expected reward per step from each state.
    """
    parts = bsccs(P)
    recurrent = parts.recurrent
    earning = np.zeros(parts.count, dtype=bool)
    earning[parts.component[recurrent & (rewards > 0)]] = True
    hot = recurrent & earning[np.maximum(parts.component, 0)]
    everywhere = np.ones(P.shape[0], dtype=bool)
    infinite = ~kernels.prob0(P, everywhere, hot)
    result = np.where(infinite, np.inf, 0.0)
    maybe = ~infinite & ~recurrent
    if maybe.any():
        A, _ = linsolve.restricted_matrix(P, maybe)
        result[maybe] = linsolve.Factorization(A).solve(
            np.asarray(rewards[maybe], dtype=np.longdouble))
    return result
