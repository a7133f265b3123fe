"""The atomic groups of an MDP's program, numbered but never listed.

An *atomic* group is one command of a lone module, or one combination of commands
(one per participating module) synchronising on an action; each gives a state at most
one choice. They are numbered group by group, a group's combinations in the order of
``itertools.product`` over its parts (the last part varying fastest).

A group's combinations multiply: eajs.6's one ``tick`` group has parts of 4, 6, 6, 85,
6, 6, 6 and 6 commands, 15.9 million combinations, of which a chunk enables a few
dozen. Listed as objects they took 8 GB before the first state was expanded, so here a
combination is decoded from its number only when it is expanded, and enumerated only
where some state enables it (:meth:`AtomicGroups.enabled_somewhere`).
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.explore.compile.equalities import EqualityIndex
from veribattery.explore.compile.program import ChoiceGroup, CompiledCommand, Program

__all__ = ["AtomicGroups"]


@dataclass(frozen=True, slots=True)
class AtomicGroups:
    """The atomic groups of *program*'s groups, by number (see the module docstring).

    :param groups: the program's groups.
    :param starts: ``len(groups) + 1`` numbers: where each group's combinations begin,
        then their count (the number of the self-loop that fixes a deadlock). Python
        ints: a group is found by :func:`bisect.bisect_right` for one number (a numpy
        call per decoded group cost more than the decoding), by ``np.searchsorted``
        for many.
    """

    groups: tuple[ChoiceGroup, ...]
    starts: tuple[int, ...]

    @classmethod
    def of(cls, program: Program) -> AtomicGroups:
        sizes = [math.prod(len(part) for part in group.parts) for group in program.groups]
        return cls(program.groups, (0, *itertools.accumulate(sizes)))

    def __len__(self) -> int:
        return self.starts[-1]

    def __getitem__(self, number: int) -> ChoiceGroup:
        """The atomic group numbered *number*: one command per part of its group."""
        group = bisect.bisect_right(self.starts, number) - 1
        if not 0 <= group < len(self.groups):
            raise IndexError(number)
        rest = number - self.starts[group]
        picked: list[tuple[CompiledCommand]] = []
        for part in reversed(self.groups[group].parts):
            rest, position = divmod(rest, len(part))
            picked.append((part[position],))
        return ChoiceGroup(self.groups[group].action, tuple(reversed(picked)))

    @property
    def actions(self) -> tuple[str, ...]:
        """``""`` (unlabelled), then every action of a group, sorted."""
        return ("", *sorted({g.action for g in self.groups if g.action is not None}))

    def group_of(self, numbers: IntArray) -> IntArray:
        """Per atomic group number, its group's index (``len(groups)`` for the number of
        the deadlock's self-loop, :func:`len`, and past it). One search per number: made
        once for all of a build's choices, then read by :meth:`action_indices` and
        :meth:`with_action`."""
        return np.searchsorted(np.array(self.starts, dtype=np.int64), numbers,
                               side="right") - 1

    def action_indices(self, groups: IntArray) -> IntArray:
        """Per group index (:meth:`group_of`), its action's index in :attr:`actions` (0:
        none, as the deadlock's self-loop)."""
        actions = self.actions
        per_group = np.array([0 if g.action is None else actions.index(g.action)
                              for g in self.groups] + [0], dtype=np.int64)
        return per_group[groups]

    def with_action(self, groups: IntArray, action: str | None) -> BoolArray:
        """Per group index (:meth:`group_of`), whether the group synchronises on *action*
        (never the deadlock's self-loop)."""
        matching = np.array([g.action == action for g in self.groups] + [False])
        return np.asarray(matching[groups], dtype=bool)

    def enabled_somewhere(self, frontier: IntArray) -> Iterator[int]:
        """The numbers of the atomic groups enabled in some state of *frontier*, lazily
        in increasing order.

        Each command's guard is evaluated once, and a group's combinations are walked
        as the tree of their prefixes: a prefix whose commands are enabled together
        nowhere is dismissed with all its combinations at once (firewire: ~5,000
        combinations per chunk, ~5 enabled; looking at each in turn cost ~1 s). The
        guards are evaluated in the order :func:`expand_group` reads them, stopping
        where it stops, so no guard is evaluated that it would not evaluate.
        """
        guards: dict[int, BoolArray | None] = {}
        for group in range(len(self.groups)):
            yield from self.enabled_in(group, frontier, guards)

    def enabled_in(self, group: int, frontier: IntArray,
                   guards: dict[int, BoolArray | None]) -> Iterator[int]:
        """:meth:`enabled_somewhere` of the *group*-th group alone (*guards*: the
        commands' guards on *frontier* evaluated so far, by the command's identity)."""
        offset = self.starts[group]
        chosen = self.groups[group]
        yield from (offset + index for index in
                    _combinations(chosen.parts, frontier, guards, indexes=chosen.indexes))


def _combinations(parts: tuple[tuple[CompiledCommand, ...], ...], frontier: IntArray,
                  guards: dict[int, BoolArray | None], enabled: BoolArray | None = None,
                  prefix: int = 0, *, indexes: tuple[EqualityIndex | None, ...] = ()
                  ) -> Iterator[int]:
    """The combinations of one command per part enabled together somewhere, numbered
    within the group (the last part varying fastest) after the commands chosen so far
    (*prefix*, enabled on *enabled*: None while they all hold everywhere). A part with
    an equality index (*indexes*, per part) is looked up once and walked only over the
    commands it enables somewhere, in their order."""
    if not parts:
        yield prefix
        return
    index = indexes[0] if indexes else None
    if index is not None:
        table = _indexed(index, frontier, guards)
        for position in np.flatnonzero(table.any(axis=0)).tolist():
            column = table[:, position]
            together = column if enabled is None else enabled & column
            if enabled is not None and not together.any():
                continue
            yield from _combinations(parts[1:], frontier, guards, together,
                                     prefix * len(parts[0]) + position, indexes=indexes[1:])
        return
    for position, command in enumerate(parts[0]):
        joint = enabled
        if not command.always:
            holds = _guard(command, frontier, guards)
            if holds is None:
                continue
            joint = holds if enabled is None else enabled & holds
            if enabled is not None and not joint.any():
                continue
        yield from _combinations(parts[1:], frontier, guards, joint,
                                 prefix * len(parts[0]) + position, indexes=indexes[1:])


def _indexed(index: EqualityIndex, frontier: IntArray,
             guards: dict[int, BoolArray | None]) -> BoolArray:
    """The part's enabledness ``(n, commands)`` by *index*, looked up once per chunk."""
    key = id(index)
    if key not in guards:
        guards[key] = index.enabled(frontier)
    table = guards[key]
    assert table is not None
    return table


def _guard(command: CompiledCommand, frontier: IntArray,
           guards: dict[int, BoolArray | None]) -> BoolArray | None:
    """Where *command*'s guard holds in *frontier*, None where nowhere (evaluated on first
    use, then read from *guards*, keyed by the command's identity)."""
    key = id(command)
    if key not in guards:
        holds = np.asarray(command.guard(frontier), dtype=bool)
        guards[key] = holds if holds.any() else None
    return guards[key]
