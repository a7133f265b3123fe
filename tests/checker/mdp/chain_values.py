"""Values of the DTMC a strategy induces, computed independently of the MDP kernels:
dense linear algebra after graph searches written out state by state (small models)."""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import csgraph


def _can_reach(P: np.ndarray, through: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """States with a path to *seeds* whose earlier states all lie in *through*."""
    reached = seeds.copy()
    changed = True
    while changed:
        changed = False
        for s in range(P.shape[0]):
            if not reached[s] and through[s] and np.any(reached[P[s] > 0]):
                reached[s] = True
                changed = True
    return reached


def until(P: np.ndarray, remain: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Probability of ``remain U target`` in every state."""
    some = _can_reach(P, remain & ~target, target)
    unknown = np.flatnonzero(some & ~target)
    x = target.astype(float)
    if unknown.size:
        A = np.eye(unknown.size) - P[np.ix_(unknown, unknown)]
        x[unknown] = np.linalg.solve(A, P[unknown][:, target].sum(axis=1))
    return x


def reach_reward(P: np.ndarray, rewards: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Expected reward until *target*; infinite where it is not reached almost surely."""
    everywhere = np.ones(P.shape[0], dtype=bool)
    never = ~_can_reach(P, everywhere & ~target, target)
    finite = ~_can_reach(P, ~target, never)
    return _solved(P, rewards, finite, finite & ~target)


def total_reward(P: np.ndarray, rewards: np.ndarray) -> np.ndarray:
    """Expected total reward; infinite where a bottom SCC with a reward is reachable."""
    n = P.shape[0]
    count, labels = csgraph.connected_components(P > 0, directed=True, connection="strong")
    bottom = np.ones(count, dtype=bool)
    paying = np.zeros(count, dtype=bool)
    for s in range(n):
        if np.any(labels[np.flatnonzero(P[s] > 0)] != labels[s]):
            bottom[labels[s]] = False
        paying[labels[s]] |= rewards[s] > 0
    in_bottom = bottom[labels]
    finite = ~_can_reach(P, np.ones(n, dtype=bool), in_bottom & paying[labels])
    return _solved(P, rewards, finite, finite & ~in_bottom)


def _solved(P: np.ndarray, rewards: np.ndarray, finite: np.ndarray,
            unknown: np.ndarray) -> np.ndarray:
    x = np.where(finite, 0.0, math.inf)
    index = np.flatnonzero(unknown)
    if index.size:
        A = np.eye(index.size) - P[np.ix_(index, index)]
        x[index] = np.linalg.solve(A, rewards[index])
    return x
