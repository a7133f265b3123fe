"""Where each branch of a joint choice lies in its row: the parts' updates in mixed radix.

A choice of one command per part has one branch per combination of the parts' updates,
numbered with the last part's update varying fastest (the general product's order);
these tables say, per part and update, which branches take it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from veribattery._types import FloatArray, IntArray

__all__ = ["BranchLayout", "branch_layout", "constant_row"]


@functools.lru_cache(maxsize=1024)
def constant_row(
    probabilities: tuple[tuple[float | None, ...], ...],
) -> tuple[FloatArray, float] | None:
    """The branch probabilities of a choice whose parts' probabilities are all
    constants (non-negative), multiplied in the order of the general product, and
    the product of the parts' sums; None if any is not a constant.
    """
    known = [p for part in probabilities for p in part]
    if any(p is None or p < 0 for p in known):
        return None
    layout = branch_layout(tuple(len(part) for part in probabilities))
    row = np.ones((1, layout.width), dtype=np.float64)
    total = 1.0
    for part, part_branches in zip(probabilities, layout.branches, strict=True):
        for p, branches in zip(part, part_branches, strict=True):
            assert p is not None
            if p != 1.0:
                row[:, branches] *= p
        total *= float(sum(p for p in part if p is not None))
    row.flags.writeable = False
    return row[0], total


@dataclass(frozen=True, slots=True)
class BranchLayout:
    """Per part and update, the branches (columns of a choice's row) that take it."""

    width: int
    branches: tuple[tuple[slice | IntArray, ...], ...]


@functools.lru_cache(maxsize=256)
def branch_layout(sizes: tuple[int, ...]) -> BranchLayout:
    """Branches in mixed radix over the parts' updates, the last part's fastest."""
    width = math.prod(sizes)
    parts: list[tuple[slice | IntArray, ...]] = []
    inner = width
    for size in sizes:
        inner //= size
        digit = (np.arange(width) // inner) % size
        if size == 1:
            parts.append((slice(None),))
        elif inner == 1:
            parts.append(tuple(slice(u, None, size) for u in range(size)))
        else:
            parts.append(tuple(np.flatnonzero(digit == u) for u in range(size)))
    return BranchLayout(width, tuple(parts))
