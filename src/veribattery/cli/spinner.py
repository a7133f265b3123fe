"""The terminal's spinner, drawn once there is work to watch.

A command refused before any work (a ``--const`` of the wrong type, found when the
model's constants are resolved) would otherwise draw "exploring states…" and erase it
in the same instant. :class:`DeferredStatus` draws rich's status line at its first
update (the builder's first layer, a check's first stage) or after
:data:`FIRST_DRAW_S`, whichever comes first.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

__all__ = ["FIRST_DRAW_S", "DeferredStatus"]

#: Seconds of silent work (parsing a large model) after which the spinner is drawn.
FIRST_DRAW_S = 0.25


class DeferredStatus:
    """A status line made by *make* (rich's ``Console.status``) once it is due; until
    then its text is kept. Call :meth:`stop` when the work ends."""

    def __init__(self, make: Callable[[str], Any], text: str) -> None:
        self._make, self._text = make, text
        self._status: Any = None
        self._stopped = False
        self._lock = threading.Lock()
        self._timer = threading.Timer(FIRST_DRAW_S, self._draw)
        self._timer.daemon = True
        self._timer.start()

    def update(self, text: Any) -> None:
        """Show *text* (drawing the line now if it is not drawn yet)."""
        with self._lock:
            self._text = text
            if self._status is not None:
                self._status.update(text)
                return
        self._draw()

    def stop(self) -> None:
        """Erase the line if it was drawn; it is never drawn after this."""
        self._timer.cancel()
        with self._lock:
            self._stopped = True
            if self._status is not None:
                self._status.stop()

    def _draw(self) -> None:
        with self._lock:
            if self._status is None and not self._stopped:
                self._status = self._make(self._text)
                self._status.start()
