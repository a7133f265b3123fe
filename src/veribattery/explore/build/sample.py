"""A uniform sample of a wide BFS layer, expanded to estimate the layer's transitions.

The memory guard needs to know early whether a layer of hundreds of thousands of
states will fit. Its first chunk is no sample of it: herman's first layer (every
state is initial) starts with the states of most tokens, whose successors outnumber
the average twentyfold. A few thousand states drawn uniformly from the rest of the
layer are: their mean number of branches, with its standard error, bounds the
layer's from below with near certainty at a few standard errors.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from veribattery._types import IntArray
from veribattery.errors import ModelError

__all__ = ["BranchSample", "sampled_branches"]

#: States drawn from a layer, and expanded at once (bounds the successor rows held).
SAMPLE = 2048
_PIECE = 256


@dataclass(frozen=True, slots=True)
class BranchSample:
    """Branches per state of a uniform sample of a layer's states.

    :param size: states drawn.
    :param mean: their mean number of branches.
    :param error: the standard error of that mean (corrected for a finite layer).
    """

    size: int
    mean: float
    error: float

    def at_least(self, states: int, z: float) -> float:
        """Branches of *states* such states, bounded from below: the mean less *z*
        standard errors (never below 0)."""
        return max(0.0, self.mean - z * self.error) * states


def sampled_branches(rows_at: Callable[[IntArray], IntArray],
                     branches_of: Callable[[IntArray], IntArray],
                     low: int, high: int, size: int = SAMPLE) -> BranchSample | None:
    """Expand a uniform sample of the states ``low..high-1``.

    :param rows_at: the rows of states given by number.
    :param branches_of: per row of a frontier, its number of branches.
    :return: the sample's statistics, or None if expanding it raised a model error
        (the search reports that error, at its first state in order, when it gets there).
    """
    count = high - low
    # A fixed seed: the same model gets the same estimate, run after run.
    picks = np.sort(np.random.default_rng(0).choice(count, size=min(size, count),
                                                    replace=False)) + low
    try:
        counts = np.concatenate([
            branches_of(rows_at(picks[i:i + _PIECE])) for i in range(0, picks.size, _PIECE)])
    except ModelError:
        return None
    spread = float(counts.std(ddof=1)) if counts.size > 1 else 0.0
    finite = math.sqrt(max(0.0, 1.0 - counts.size / count))
    return BranchSample(counts.size, float(counts.mean()),
                        spread / math.sqrt(counts.size) * finite)
