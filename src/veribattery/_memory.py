"""Returning freed heap memory to the system (glibc only; elsewhere nothing).

glibc serves a block of at least ``M_MMAP_THRESHOLD`` bytes by a mapping of its own,
but the threshold rises (up to 32 MiB) each time such a block is freed; from then on
arrays below it come from the heap, whose free space is reused but rarely handed
back. The builder (between layers) and the checker (between properties) allocate and
free many arrays of a few to a few dozen MB, so they call :func:`trim_heap` at those
boundaries: ``malloc_trim`` hands every free page of the heap back at once.

A fixed 1 MiB mapping threshold was tried instead: it saved about 90 MB on the 11x11
mission but doubled the check stage of the baseline mission (every temporary of a
megabyte or more was mapped, zero-filled by page faults and unmapped again:
+0.5 s of system time per run), so it is not used.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

__all__ = ["TRIM_MIN_STATES", "trim_for", "trim_heap"]

#: Heaps are trimmed between stages only for models of at least this many states: the
#: trim is for the peak memory of large models; on the paper's mission (176,481
#: states) its ~2 ms per call were a tenth of a structure-reusing sweep point.
TRIM_MIN_STATES = 1_000_000


@functools.cache
def _malloc_trim() -> Callable[[int], int] | None:
    import ctypes

    try:  # the soname itself: ctypes.util.find_library would spawn ldconfig
        trim: Callable[[int], int] = ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None
    return trim


def trim_heap() -> bool:
    """Hand the heap's free pages back to the system.

    :returns: whether glibc's ``malloc_trim`` ran (False with another C library).
    """
    trim = _malloc_trim()
    if trim is None:
        return False
    trim(0)
    return True


def trim_for(states: int) -> None:
    """:func:`trim_heap` when a model of *states* states reaches :data:`TRIM_MIN_STATES`."""
    if states >= TRIM_MIN_STATES:
        trim_heap()
