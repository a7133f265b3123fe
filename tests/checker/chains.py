"""Hand-built DTMCs for the checker tests: a dict of rows in, a DTMC out."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.sparse as sp
from hypothesis import strategies as st

from veribattery.explore.dtmc import DTMC, RewardVectors

Rows = Mapping[int, Mapping[int, float]]


def matrix(rows: Rows, n: int) -> sp.csr_matrix:
    """A CSR matrix from ``{source: {target: probability}}``; missing rows self-loop."""
    src, dst, prob = [], [], []
    for s in range(n):
        for t, p in rows.get(s, {s: 1.0}).items():
            src.append(s)
            dst.append(t)
            prob.append(p)
    return sp.csr_matrix((prob, (src, dst)), shape=(n, n), dtype=np.float64)


def draw_stochastic(draw: st.DrawFn, n: int) -> sp.csr_matrix:
    """A random n x n stochastic matrix for hypothesis: 1-3 successors per row, integer
    weights 1..9 normalised in float64."""
    dense = np.zeros((n, n))
    for s in range(n):
        succ = draw(st.lists(st.integers(0, n - 1), min_size=1, max_size=3, unique=True))
        weights = draw(st.lists(st.integers(1, 9), min_size=len(succ), max_size=len(succ)))
        dense[s, succ] = np.asarray(weights) / sum(weights)
    return sp.csr_matrix(dense)


def mask(n: int, states: Sequence[int]) -> np.ndarray:
    """A boolean mask with *states* set."""
    result = np.zeros(n, dtype=bool)
    result[list(states)] = True
    return result


def dtmc(
    rows: Rows,
    n: int,
    labels: Mapping[str, Sequence[int]] = {},
    rewards: Mapping[str, tuple[Sequence[float], Sequence[float]]] = {},
    initial: Sequence[int] = (0,),
    states: np.ndarray | None = None,
    variable_names: tuple[str, ...] = ("s",),
) -> DTMC:
    """A DTMC from rows, label state lists and ``{name: (state, transition)}`` rewards.

    By default the single variable ``s`` holds the state index.
    """
    table = np.arange(n, dtype=np.int64).reshape(n, 1) if states is None else states
    masks = {name: mask(n, members) for name, members in labels.items()}
    masks.setdefault("init", mask(n, initial))
    masks.setdefault("deadlock", mask(n, []))
    structures = tuple(
        RewardVectors(name, np.asarray(st, dtype=np.float64), np.asarray(tr, dtype=np.float64))
        for name, (st, tr) in rewards.items()
    )
    return DTMC(matrix(rows, n), table, variable_names, np.asarray(initial, dtype=np.int64),
                masks, structures)


def knuth_die() -> DTMC:
    """Knuth-Yao's die from fair coins: states 0..6 flip, 7..12 show faces 1..6.

    Reward ``"flips"`` is 1 per step in the flipping states (transition reward).
    """
    h = 0.5
    rows = {
        0: {1: h, 2: h}, 1: {3: h, 4: h}, 2: {5: h, 6: h},
        3: {1: h, 7: h}, 4: {8: h, 9: h}, 5: {10: h, 11: h}, 6: {2: h, 12: h},
    }
    faces = {f"face{f}": [6 + f] for f in range(1, 7)}
    flips = ([0.0] * 13, [1.0] * 7 + [0.0] * 6)
    return dtmc(rows, 13, labels={**faces, "done": range(7, 13)}, rewards={"flips": flips})


def gamblers_ruin(n: int, p: float, initial: Sequence[int] = (1,)) -> DTMC:
    """Fortune 0..n, up with probability *p*, down otherwise; 0 and n absorb.

    Labels ``"win"`` (n), ``"lose"`` (0), ``"end"`` (both); reward ``"steps"`` is a
    state reward of 1 in every non-absorbing state.
    """
    rows = {i: {i + 1: p, i - 1: 1.0 - p} for i in range(1, n)}
    steps = [0.0] + [1.0] * (n - 1) + [0.0]
    return dtmc(rows, n + 1, labels={"win": [n], "lose": [0], "end": [0, n]},
                rewards={"steps": (steps, [0.0] * (n + 1))}, initial=initial)
