"""Progress of a long build and check when stderr is not a terminal, and the state limit.

On a terminal the spinner of :func:`~veribattery.cli.output.build_progress` shows the
count; in a log (CI, ``2> build.log``, a batch job) :class:`PlainProgress` writes a
plain line now and then instead -- the stage, the states explored, how far a solve
is -- so that a long run can be told from a hang, while a short one prints nothing.
:func:`limited` stops a build that finds more states than ``--max-states`` allows.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from veribattery.errors import ModelTooLarge, OptionError

if TYPE_CHECKING:
    from veribattery.pipeline import CheckProgress

__all__ = ["FIRST_LINE_S", "INTERVALS_VARIABLE", "LINE_EVERY_S", "BuildProgress", "PlainProgress",
           "intervals", "limited", "rate_text", "solve_text"]

#: A build shorter than this prints nothing (the common case stays silent).
FIRST_LINE_S = 5.0
#: Seconds between two lines after the first.
LINE_EVERY_S = 10.0
#: ``FIRST,EVERY`` seconds in place of :data:`FIRST_LINE_S` and :data:`LINE_EVERY_S`
#: (``0,0``: a line at every report; for tests and for watching a slow run closely).
INTERVALS_VARIABLE = "VERIBATTERY_PROGRESS_S"

#: Told ``(states found so far, frontier size)`` after each BFS layer.
BuildProgress = Callable[[int, int], None]


def rate_text(states: int, elapsed: float) -> str:
    """``"12,345 states/s"`` (nothing to divide by in the first instant: ``"…"``)."""
    return f"{states / elapsed:,.0f} states/s" if elapsed > 0 else "… states/s"


def intervals() -> tuple[float | None, float | None]:
    """``(first, every)`` from :data:`INTERVALS_VARIABLE`, or ``(None, None)`` (the
    defaults) when it is not set.

    :raises OptionError: when it is set but not two non-negative numbers.
    """
    text = os.environ.get(INTERVALS_VARIABLE)
    if text is None:
        return None, None
    try:
        first, every = (float(part) for part in text.split(","))
    except ValueError:
        first = every = -1.0
    if not (first >= 0 and every >= 0):
        raise OptionError(f"{INTERVALS_VARIABLE}={text!r}: give FIRST,EVERY seconds, e.g. 0,1")
    return first, every


def solve_text(subject: str, done: int, total: int, unit: str, seconds: float,
               room: int | None = None) -> str:
    """``"solving P=? [ F x ]: 3,210 of 9,420 states, 12 s"`` (no subject: ``"solving: …"``;
    a *total* of 0, not known beforehand: ``"solving: weighted solve 12, 40 s"``).

    :param room: the most characters the line may take: a longer subject is cut with an
        ellipsis, so that the count stays in view (a spinner's line at 80 columns).
    """
    count = f"{unit} {done:,}" if total <= 0 else f"{done:,} of {total:,} {unit}"
    tail = f": {count}, {seconds:.0f} s"
    about = f" {subject}" if subject else ""
    if room is not None and len("solving") + len(about) + len(tail) > room:
        keep = room - len("solving") - len(tail) - 2  # (the space and the ellipsis)
        about = f" {subject[:keep]}…" if keep > 0 else ""
    return f"solving{about}{tail}"


class PlainProgress:
    """Plain lines on stderr during a long run: the stage, then while building the states
    found, frontier, rate and time so far, while solving the states (or iterations)
    done and the time the property has taken.

    Nothing is written until *first* seconds have passed (a stage that began before
    is written then, before the first count); from then on every stage is written
    as it begins, and a count at most every *every* seconds.

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
        self._start = self._since = clock()
        self._due = self._start + (FIRST_LINE_S if first is None else first)
        self._talking = False  # whether a line has been written: a long run
        self._stage: str | None = None  # the stage begun and not yet written
        self._subject = ""  # the property being checked

    def __call__(self, states: int, frontier: int) -> None:
        now = self._clock()
        if not self._line_due(now):
            return
        elapsed = now - self._start
        self._write(f"exploring states: {states:,} found, frontier {frontier:,}, "
                    f"{rate_text(states, elapsed)}, {elapsed:.0f} s")

    def starting(self, text: str) -> None:
        """A stage begins: written now in a long run, else kept until the first line."""
        self._begin(text, "")

    def step(self, text: str) -> None:
        """A step of a run made of many short ones begins (a forecast's next age): a stage,
        and written as soon as a line is due, since such a run reports no counts."""
        self.starting(text)
        self._line_due(self._clock())

    def checking(self, number: int, count: int, text: str) -> None:
        """Property *number* of *count* (its formula *text*) is checked next."""
        self._begin(f"checking property {number} of {count}: {text}", text)

    def solving(self, done: int, total: int, unit: str) -> None:
        """A solve has *done* of *total* *unit* behind it."""
        now = self._clock()
        if self._line_due(now):
            self._write(solve_text(self._subject, done, total, unit, now - self._since))

    def stage(self, text: str) -> None:
        """Say that a new stage starts (at once, however short the run so far); a solve
        within it is counted from now."""
        self._write(text)
        self._subject, self._since = "", self._clock()

    def _begin(self, text: str, subject: str) -> None:
        self._stage, self._subject, self._since = text, subject, self._clock()
        if self._talking:
            self._tell_stage()

    def _line_due(self, now: float) -> bool:
        """Whether a count is due at *now*; if it is, the next is due *every* seconds
        later and the stage (if not yet written) is written before it."""
        if now < self._due:
            return False
        self._due = now + self._every
        self._tell_stage()
        return True

    def _tell_stage(self) -> None:
        self._talking = True
        if self._stage is not None:
            self._write(self._stage)
            self._stage = None


def limited(progress: CheckProgress | None, max_states: int | None) -> CheckProgress | None:
    """*progress*, stopping the build with :class:`ModelTooLarge` once more than
    *max_states* states are found (checked after each BFS layer, as the memory guard is)."""
    return progress if max_states is None else _Limited(progress, max_states)


class _Limited:
    """:func:`limited`'s progress: the state limit, then *progress* (if any) hears all."""

    def __init__(self, progress: CheckProgress | None, max_states: int) -> None:
        self._progress = progress
        self._max_states = max_states

    def __call__(self, states: int, frontier: int) -> None:
        if states > self._max_states:
            raise ModelTooLarge(f"model too large: more than --max-states {self._max_states:,} "
                                f"states ({states:,} found so far); the build stopped")
        if self._progress is not None:
            self._progress(states, frontier)

    def starting(self, text: str) -> None:
        if self._progress is not None:
            self._progress.starting(text)

    def checking(self, number: int, count: int, text: str) -> None:
        if self._progress is not None:
            self._progress.checking(number, count, text)

    def solving(self, done: int, total: int, unit: str) -> None:
        if self._progress is not None:
            self._progress.solving(done, total, unit)
