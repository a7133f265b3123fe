"""Fold the long, uneventful middle of a path so that its story fits on a screen.

A failure path of the mission is dozens of recharge trips followed by the sortie
that fails. What matters is the start and the end: the steps after the last
*marker* action (``recharge`` for the mission: the final sortie), or at least the
last *tail* steps. The steps between are summarised by action counts.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["Fold", "fold_path"]


@dataclass(frozen=True, slots=True)
class Fold:
    """Steps ``first..last`` (inclusive) folded away, with how often each action occurs there."""

    first: int
    last: int
    actions: tuple[tuple[str, int], ...]

    def describe(self, marker: str | None = None) -> str:
        """One line, e.g. ``… 22 recharge trips (steps 3-540: 88 inspect, 22 recharge) …``."""
        counts = dict(self.actions)
        what = ", ".join(f"{n} {a}" for a, n in self.actions)
        steps = f"steps {self.first}-{self.last}"
        if marker is not None and counts.get(marker):
            return f"… {counts[marker]} {marker} trips ({steps}: {what}) …"
        return f"… {self.last - self.first + 1} steps ({steps}: {what}) …"


def fold_path(
    actions: Sequence[str], *, marker: str | None = None, head: int = 2, tail: int = 12,
) -> tuple[range, Fold | None, range]:
    """Split a path's steps into the shown head, the folded middle, and the shown end.

    :param actions: the action of each step.
    :param marker: the action after whose last occurrence everything is shown.
    :param head: steps always shown at the start.
    :param tail: steps always shown at the end.
    :return: the head steps, the fold (None when nothing is worth folding), the end steps.
    """
    n = len(actions)
    end = max(0, n - tail)
    if marker is not None and marker in actions:
        last = max(i for i, a in enumerate(actions) if a == marker)
        end = min(end, last)
    if end - head < 3:  # folding fewer steps than the fold's own line saves nothing
        return range(n), None, range(n, n)
    middle = Counter(actions[head:end])
    fold = Fold(head, end - 1, tuple(middle.most_common()))
    return range(head), fold, range(end, n)
