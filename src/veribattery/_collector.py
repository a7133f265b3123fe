"""Garbage collection spaced out while a model is parsed, flattened and built.

Parsing and compiling a model make millions of small objects that live to the end of the
build (expression trees, compiled nodes), few of them garbage in cycles. Python collects
its youngest generation every 700 allocations, and each collection re-scans the young
survivors: on a 200 x 200 farm ~40 % of the check (20 s against 12 s) and 3.4 of
oscillators 6-10's 5.3 s build, for the same peak memory. The CLI spaces collections out
for its whole process (:func:`veribattery._startup.start_process`); a library caller (a
notebook) gets the same while one of veribattery's stages runs, and its own threshold
back afterwards.
"""

from __future__ import annotations

import functools
import gc
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import ParamSpec, TypeVar

__all__ = ["YOUNG_COLLECTION_EVERY", "collections_spaced", "spaced_collections"]

#: Allocations between two collections of the youngest generation (Python's default: 700).
YOUNG_COLLECTION_EVERY = 50_000

_P = ParamSpec("_P")
_R = TypeVar("_R")


@contextmanager
def spaced_collections() -> Iterator[None]:
    """Collect the youngest generation at most every :data:`YOUNG_COLLECTION_EVERY`
    allocations inside the block; a threshold already as large, or 0 (collection off),
    is kept. The caller's thresholds are restored on the way out."""
    before = gc.get_threshold()
    if before[0] == 0 or before[0] >= YOUNG_COLLECTION_EVERY:
        yield
        return
    gc.set_threshold(YOUNG_COLLECTION_EVERY, *before[1:])
    try:
        yield
    finally:
        gc.set_threshold(*before)


def collections_spaced(stage: Callable[_P, _R]) -> Callable[_P, _R]:
    """*stage* run inside :func:`spaced_collections`."""

    @functools.wraps(stage)
    def spaced(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        with spaced_collections():
            return stage(*args, **kwargs)

    return spaced
