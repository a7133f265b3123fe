"""Progress of a long state-space build when stderr is not a terminal, and the state limit.

On a terminal the spinner of :func:`~veribattery.cli.output.build_progress` shows the
count; in a log (CI, ``2> build.log``, a batch job) :class:`PlainProgress` writes a
plain line now and then instead, so that a long build can be told from a hang.
:func:`limited` stops a build that finds more states than ``--max-states`` allows.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from veribattery.errors import ModelTooLarge

__all__ = ["FIRST_LINE_S", "LINE_EVERY_S", "BuildProgress", "PlainProgress", "limited", "rate_text"]

#: A build shorter than this prints nothing (the common case stays silent).
FIRST_LINE_S = 5.0
#: Seconds between two lines after the first.
LINE_EVERY_S = 10.0

#: Told ``(states found so far, frontier size)`` after each BFS layer.
BuildProgress = Callable[[int, int], None]


def rate_text(states: int, elapsed: float) -> str:
    """``"12,345 states/s"`` (nothing to divide by in the first instant: ``"…"``)."""
    return f"{states / elapsed:,.0f} states/s" if elapsed > 0 else "… states/s"


class PlainProgress:
    """Plain lines on stderr during a build: states found, frontier, rate, time so far.

    :param write: writes one line (stderr).
    :param clock: seconds, monotonic (injected by the tests).
    :param first: seconds before the first line (default :data:`FIRST_LINE_S`).
    :param every: seconds between lines (default :data:`LINE_EVERY_S`).
    """

    def __init__(self, write: Callable[[str], None], clock: Callable[[], float] = time.monotonic,
                 first: float | None = None, every: float | None = None) -> None:
        self._write = write
        self._clock = clock
        self._every = LINE_EVERY_S if every is None else every
        self._start = clock()
        self._due = self._start + (FIRST_LINE_S if first is None else first)

    def __call__(self, states: int, frontier: int) -> None:
        now = self._clock()
        if now < self._due:
            return
        self._due = now + self._every
        elapsed = now - self._start
        self._write(f"exploring states: {states:,} found, frontier {frontier:,}, "
                    f"{rate_text(states, elapsed)}, {elapsed:.0f} s")

    def stage(self, text: str) -> None:
        """Say that a new stage starts."""
        self._write(text)


def limited(progress: BuildProgress | None, max_states: int | None) -> BuildProgress | None:
    """*progress*, stopping the build with :class:`ModelTooLarge` once more than
    *max_states* states are found (checked after each BFS layer, as the memory guard is)."""
    if max_states is None:
        return progress

    def watch(states: int, frontier: int) -> None:
        if states > max_states:
            raise ModelTooLarge(f"model too large: more than --max-states {max_states:,} "
                                f"states ({states:,} found so far); the build stopped")
        if progress is not None:
            progress(states, frontier)

    return watch
