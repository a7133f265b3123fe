"""Where long solves say how far they are, for a caller that shows it.

A :class:`SolveMonitor` belongs to a workspace and is handed to the solvers made
with it; its caller listens while its checks run (:meth:`SolveMonitor.listening`).
The solvers tell it after each segment or iteration, never per state, and with no
listener a report is one attribute test: the common, short check pays nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

__all__ = ["SolveListener", "SolveMonitor"]

#: Told ``(done, total, unit)``: e.g. ``(3_210_000, 9_420_422, "states")`` solved so
#: far, or ``(120, 20_000, "iterations")`` of an iterative method (total: its cap).
SolveListener = Callable[[int, int, str], None]


class SolveMonitor:
    """Relays the progress of the solves made with it to the current listener, if any."""

    __slots__ = ("_listener",)

    def __init__(self) -> None:
        self._listener: SolveListener | None = None

    def __call__(self, done: int, total: int, unit: str = "states") -> None:
        """Report that *done* of *total* *unit* are solved (nothing when no one listens)."""
        if self._listener is not None:
            self._listener(done, total, unit)

    @property
    def heard(self) -> bool:
        """Whether a listener hears the reports now (else a solver need not make them)."""
        return self._listener is not None

    @contextmanager
    def listening(self, listener: SolveListener | None) -> Iterator[None]:
        """*listener* hears the reports inside the block (the previous one again after)."""
        previous, self._listener = self._listener, listener
        try:
            yield
        finally:
            self._listener = previous
