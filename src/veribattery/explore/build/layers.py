"""The layers of a breadth-first search: the transitions out of each frontier.

The builder keeps one :class:`Layer` per chunk of a BFS layer until the DTMC is
assembled; structure re-use keeps them to re-price. :class:`Layers` merges
consecutive small ones as the search goes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from veribattery._types import FloatArray, IntArray
from veribattery.explore.build.fused import Expansion

__all__ = ["Layer", "Layers"]

_INT32_MAX = int(np.iinfo(np.int32).max)


@dataclass(frozen=True, slots=True)
class Layer:
    """The transitions out of one frontier and its states' choice counts.

    *dropped* lists the positions, in the frontier's branch order before
    zero-probability branches were dropped, of those branches; *branches* counts
    the branches before dropping. Both let a re-evaluation (see ``reuse.structure``) prove
    that the same branches exist.
    """

    rows: IntArray
    columns: IntArray
    probabilities: FloatArray
    choices: IntArray
    action_choices: dict[str | None, IntArray]
    dropped: IntArray
    branches: int


class Layers:
    """The layers of a search, consecutive small ones merged into one.

    A mission model has ~700 BFS layers of a few hundred branches: kept apart, each
    costs a dozen numpy calls here and again wherever the layers are used (the
    transition matrix, the action shares, structure re-use). Pending layers (their
    successor rows dropped) are merged once they hold ``_MERGE_BRANCHES`` branches
    (a large chunk alone at once), their indices narrowed as the builder keeps them.

    :param counts: the dtype of the choice counts (see ``builder``).
    """

    def __init__(self, counts: np.dtype[Any]) -> None:
        self._counts = counts
        self._pending: list[_Pending] = []
        self._branches = 0
        self.layers: list[Layer] = []

    def add(self, found: Expansion, low: int, columns: IntArray, states: int) -> None:
        """Keep the expansion of the frontier from state *low* (its targets numbered
        *columns*; *states* known so far)."""
        self._pending.append((found.source, low, columns, found.probability, found.choices,
                              found.action_choices, found.dropped, found.branches))
        self._branches += columns.size
        if self._branches >= _MERGE_BRANCHES:
            self._flush(states)

    def done(self, states: int) -> list[Layer]:
        """Every layer, the pending ones merged (*states*: the number of states)."""
        self._flush(states)
        return self.layers

    def _flush(self, states: int) -> None:
        if self._pending:
            self.layers.append(_merged(self._pending, states, self._counts))
        self._pending, self._branches = [], 0


#: What a layer keeps of an expansion until it is merged: source, first state,
#: columns, probability, choices, action choices, dropped, branches.
_Pending = tuple[IntArray, int, IntArray, FloatArray, IntArray, dict[str | None, IntArray],
                 IntArray, int]
#: Branches of consecutive layers merged into one (1.5 MB before narrowing).
_MERGE_BRANCHES = 1 << 15


def _merged(pending: list[_Pending], states: int, counts: np.dtype[Any]) -> Layer:
    """One layer of the *pending* expansions (*states*: the number of states known)."""
    index_type = np.int32 if states < _INT32_MAX else np.int64
    source, low, columns, probability, choices, action_choices, dropped, branches = zip(
        *pending, strict=True)
    offsets = np.cumsum((0, *branches[:-1])).tolist()
    actions = dict.fromkeys(a for found in action_choices for a in found)
    return Layer(
        _joined([s + first for s, first in zip(source, low, strict=True)], index_type),
        _joined(columns, index_type),
        _joined(probability, np.float64),
        _joined(choices, counts),
        {a: _joined([found.get(a, np.zeros(c.size, dtype=np.int64))
                     for found, c in zip(action_choices, choices, strict=True)], counts)
         for a in actions},
        _joined([d + o for d, o in zip(dropped, offsets, strict=True)], np.int64),
        sum(branches),
    )


def _joined(parts: Sequence[np.ndarray], dtype: Any) -> np.ndarray:
    """The concatenation of *parts* as *dtype* (one copy)."""
    if len(parts) == 1:
        return parts[0].astype(dtype, copy=False)
    return np.concatenate(parts, dtype=dtype, casting="unsafe")
