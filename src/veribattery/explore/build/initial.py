"""The initial states of a flat model: its variables' init values, or the states of
the variables' domain that satisfy its ``init`` block."""

from __future__ import annotations

import numpy as np

from veribattery._types import IntArray
from veribattery.errors import ModelError
from veribattery.explore.compile.expr import compile_expr
from veribattery.lang.nodes import FlatModel

__all__ = ["initial_states"]

#: Rows of the variables' domain enumerated at once when evaluating an ``init`` block.
_INIT_CHUNK = 1 << 20


def initial_states(model: FlatModel) -> IntArray:
    """The initial states of *model*: its variables' init values, or the domain
    states that satisfy its ``init`` block (enumerated in chunks, first variable
    most significant).
    """
    if model.init is None:
        return np.array([[v.init for v in model.variables]], dtype=np.int64)
    lows = np.array([v.low for v in model.variables], dtype=np.int64)
    sizes = np.array([v.high - v.low + 1 for v in model.variables], dtype=np.int64)
    total = int(np.prod(sizes.astype(object)))  # exact: the product may overflow int64
    if total > 1 << 40:
        raise ModelError(f"init block ranges over {total} states: too many to enumerate")
    predicate = compile_expr(model.init, model.variable_names)
    found = [
        rows[predicate(rows).astype(bool)]
        for rows in (
            _domain_rows(lows, sizes, s, min(s + _INIT_CHUNK, total))
            for s in range(0, total, _INIT_CHUNK)
        )
    ]
    result = np.concatenate(found) if found else np.empty((0, lows.size), dtype=np.int64)
    if result.shape[0] == 0:
        raise ModelError("the init block is satisfied by no state")
    return result


def _domain_rows(lows: IntArray, sizes: IntArray, start: int, stop: int) -> IntArray:
    """Rows ``start..stop-1`` of the domain in mixed-radix order."""
    flat = np.arange(start, stop, dtype=np.int64)
    rows = np.empty((flat.size, sizes.size), dtype=np.int64)
    for i in range(sizes.size - 1, -1, -1):
        flat, rows[:, i] = np.divmod(flat, sizes[i])
    return rows + lows
