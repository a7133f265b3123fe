"""The builder's memory guard: a state space too large for the machine is reported,
with its size so far and what it would need, before the machine runs out of memory.

Checked once per BFS layer, from what the search knows anyway: the states found, the
frontier just expanded, the next one (the states found but not yet expanded), and
the transitions. The next layer is projected from the frontier's growth; the bytes
of the search so far and of the DTMC after the next layer come from what the
builder keeps per state and per transition (:class:`Footprint`). If what the next
layer and the assembly would add exceeds the memory the system has available
(``MemAvailable`` of ``/proc/meminfo``), the search stops with
:class:`~veribattery.errors.ModelTooLarge`. A layer wider than one chunk is also
checked chunk by chunk, and at its start from a uniform sample of its states.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass

from veribattery.errors import ModelTooLarge
from veribattery.explore.build.sample import BranchSample

__all__ = ["Footprint", "MemoryGuard", "available_memory"]

#: Below this many bytes to add, the memory available is not even read (small models).
_NEGLIGIBLE = 64 << 20
#: Share of the memory available that the build may plan to use (the rest: the
#: estimate's error, the other processes, the stages after the build).
_USABLE = 0.9
#: Standard errors below a sample's mean that a wide layer is judged at (see
#: :meth:`MemoryGuard.wide_layer`): a one-sided bound that holds with near certainty.
_SAMPLE_Z = 4.0


def available_memory() -> int | None:
    """Bytes the system can give without swapping (``MemAvailable``), or None if unknown."""
    try:
        with open("/proc/meminfo", "rb") as meminfo:
            for line in meminfo:
                if line.startswith(b"MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:  # free pages only (not the page cache): an underestimate, so a safe one
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):
        return None


@dataclass(frozen=True, slots=True)
class Footprint:
    """Bytes the builder holds per state and per transition, during the search and
    once the DTMC is assembled (measured on the mission of a 20x20 farm and a 60 Ah
    battery: 2.26 GB at peak for 11.5 million states and 22.9 million transitions;
    this says 2.4 GB).

    :param width: variables per state (the assembled DTMC keeps each as int64).
    :param words: int64 words per state key (one unless the ranges' product is huge).
    """

    width: int
    words: int = 1

    def searching(self, states: int, transitions: int) -> int:
        """The search's own arrays: a key and up to eight 4-byte hash slots per state,
        the choice counts; row, column (int32) and probability per transition."""
        return states * (8 * self.words + 48) + transitions * 16

    def assembled(self, states: int, transitions: int) -> int:
        """The search's arrays plus what assembling the DTMC adds at its peak: the
        decoded states, labels, reward vectors and their temporaries, and the sparse
        matrix the transitions are moved into."""
        extra = states * (8 * self.width + 40) + transitions * 8
        return self.searching(states, transitions) + extra


class MemoryGuard:
    """Stops a search whose next layer and assembly would not fit in memory.

    One per search (it remembers the memory available, read again only when the
    need comes near it).

    :param footprint: the builder's bytes per state and transition.
    :param available: the memory available now, in bytes, or None if unknown (then
        nothing is checked); default :func:`available_memory`.
    """

    def __init__(
        self, footprint: Footprint, available: Callable[[], int | None] | None = None
    ) -> None:
        self.footprint = footprint
        self._available = available if available is not None else available_memory
        self._known: int | None = None

    def layer_done(self, states: int, expanded: int, frontier: int, transitions: int) -> None:
        """Check after a BFS layer.

        :param states: states found so far.
        :param expanded: states expanded so far (the next frontier is the rest).
        :param frontier: the size of the frontier just expanded.
        :param transitions: transitions found so far.
        :raises ModelTooLarge: if the next layer and the DTMC would not fit.
        """
        upcoming = states - expanded  # the next frontier (none: the DTMC is assembled next)
        growth = upcoming / frontier if frontier else 0.0
        later_states = states + int(upcoming * growth)
        later_transitions = transitions + int(upcoming * transitions / max(expanded, 1))
        need = (self.footprint.assembled(later_states, later_transitions)
                - self.footprint.searching(states, transitions))
        trend = "growing" if growth >= 1 else "shrinking"
        self._check(need, f"{states:,} states and {transitions:,} transitions found so far, "
                          f"the frontier {trend} {growth:.2f}x per layer",
                    f"for about {later_states:,} states")

    def chunk_done(self, states: int, transitions: int, done: int,
                   frontier: int | None = None) -> None:
        """Check after a chunk, *done* states expanded so far (of a BFS layer of
        *frontier* states; None: the MDP builder's search, which keeps no layers): the
        DTMC or MDP of what is found already must still fit. (The rest of a layer is
        not projected from its start: herman's first layer holds every state, those
        with many tokens first, and the rate of its first chunk overstates the whole
        layer's transitions twentyfold.)

        :raises ModelTooLarge: if it would not.
        """
        where = (f"{done:,} states expanded" if frontier is None
                 else f"{done:,} of a layer of {frontier:,} states expanded")
        self._check(self._assembly(states, transitions, 0),
                    f"{states:,} states and {transitions:,} transitions found so far, {where}",
                    "to assemble what is found")

    def wide_layer(self, states: int, layer: int,
                   sample: Callable[[], BranchSample | None]) -> None:
        """Check before the search expands a first layer of *layer* states wider than a
        chunk (an ``init`` block of many states), whose branching nothing tells yet.

        Its first chunk would be no guide (see :mod:`~veribattery.explore.build.sample`),
        and on herman's ring of 21 it alone holds gigabytes of successors. A uniform
        *sample* of the layer is expanded instead; the layer is refused if even the
        sample's mean less ``_SAMPLE_Z`` standard errors would not fit. (Otherwise the
        chunks go on, each checked by :meth:`chunk_done`.)

        :raises ModelTooLarge: if the sample says the layer would not fit.
        """
        found = sample()
        if found is None:
            return
        least = found.at_least(layer, _SAMPLE_Z)
        need = self._assembly(states, 0, least)
        if self._exceeds(need):
            raise self._refusal(
                need, f"{states:,} states found; the {layer:,} states of the first layer have "
                      f"about {found.mean * layer:,.0f} transitions (at least {least:,.0f}, from "
                      f"a uniform sample of {found.size:,} of them)", "to assemble those alone")

    def _assembly(self, states: int, transitions: int, more: float) -> int:
        """Bytes added by *more* transitions and assembling the DTMC of them all."""
        total = transitions + int(more)
        return (self.footprint.assembled(states, total)
                - self.footprint.searching(states, transitions))

    def _check(self, need: int, found: str, target: str) -> None:
        if self._exceeds(need):
            raise self._refusal(need, found, target)

    def _exceeds(self, need: int) -> bool:
        """Whether *need* more bytes exceed the usable share of the memory available."""
        if need < _NEGLIGIBLE:
            return False
        if self._known is None or 4 * need > self._known:  # near the limit: look again
            self._known = self._available()
        return self._known is not None and need > _USABLE * self._known

    def _refusal(self, need: int, found: str, target: str) -> ModelTooLarge:
        return ModelTooLarge(
            f"model too large for the memory available: {found}; going on needs "
            f"about {_gb(need)} more ({target}), above the {_USABLE:.0%} of the "
            f"{_gb(self._known or 0)} available that a build may plan to use")


def _gb(size: int) -> str:
    return f"{size / 1e9:.1f} GB"
