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

    :param P: row-stochastic CSR transition matrix.
    :param parts: the BSCCs of *P*.
    """
    n = P.shape[0]
    result = np.zeros(n)
    states = np.flatnonzero(parts.recurrent)
    comp = parts.component[states]
    # One representative per BSCC: its equation becomes the normalisation.
    _, first = np.unique(comp, return_index=True)
    m = states.size
    inner = sp.csr_matrix(P[states][:, states])
    balance = sp.csr_matrix((inner - sp.identity(m, format="csr")).T)
    keep = np.ones(m)
    keep[first] = 0.0
    normalise = sp.csr_matrix((np.ones(m), (first[comp], np.arange(m))), shape=(m, m))
    A = sp.diags(keep, format="csr") @ balance + normalise
    b = np.zeros(states.size)
    b[first] = 1.0
    pi = _solve(sp.csc_matrix(A), b)
    pi = np.clip(pi, 0.0, None)
    totals = np.bincount(comp, weights=pi, minlength=parts.count)
    result[states] = pi / totals[comp]
    return result


def _solve(A: sp.csc_matrix, b: FloatArray) -> FloatArray:
    """A direct sparse solve; a single-state BSCC needs none (pi = 1)."""
    if A.shape[0] == int(np.count_nonzero(b)):
        return b.copy()
    return np.asarray(spsolve(A, b), dtype=np.float64)


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


def steady_probs(P: CsrMatrix, target: BoolArray) -> FloatArray:
    """Long-run probability of being in *target*, from every state (``S=? [target]``).

    :param P: row-stochastic CSR transition matrix.
    :param target: the states counted.
    """
    parts = bsccs(P)
    pi = stationary(P, parts)
    recurrent = parts.recurrent
    mass = np.bincount(parts.component[recurrent], weights=(pi * target)[recurrent],
                       minlength=parts.count).astype(np.float64)
    return np.clip(absorbed(P, parts, mass), 0.0, 1.0)


def long_run_rewards(P: CsrMatrix, rewards: FloatArray) -> FloatArray:
    """Long-run average reward per step from every state (``R=? [S]``).

    :param P: row-stochastic CSR transition matrix.
    :param rewards: expected reward per step taken from each state (state + transition).
    """
    parts = bsccs(P)
    pi = stationary(P, parts)
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
