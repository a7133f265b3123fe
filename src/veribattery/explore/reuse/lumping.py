"""Bisimulation quotients of acyclic DTMCs, for sweeps that check many points of one structure.

States that carry the same labels, rewards and values of the variables the properties
read, and that move with the same probabilities to the same blocks of such states, have
the same value for every PCTL property and expected reward (strong probabilistic
bisimulation). A sweep that re-uses one state space checks each point on the quotient
chain of those blocks instead: on the paper's mission 176,481 states become ~74,000.

**Exact quotients.** Results are certified, so the quotient must be the chain's exact
lumping: every quotient entry is one stored probability of the chain, never a sum of
two. A state whose two successors fall into one block would need ``p + q``, which
float64 may round (``fl(0.1) + fl(0.9)`` is not their exact sum), so the larger of such
successors is split off and the partition made again (a *round*). In the last round
every state of a block ``B`` has at most one entry into each block ``C``, and the same
one as every other state of ``B``: ``P 1_C = 1_B Q_BC`` holds exactly, and with it the
quotient's values and certified bounds are the chain's.

**The partition of a point.** On an acyclic chain (self-loops allowed) two states are
put together when their *recursive signatures* are equal: their seeds (labels,
rewards, read variables; a unique tag for initial and split states) and the multisets
of (successor's signature, probability bits). It is computed level by level, as 64-bit
hashes (a state's successors lie on lower levels), then checked exactly: every state
against its block's representative. A hash clash that merged unequal states is caught
there and the hashes are made again with another salt. Chains with a cycle get no
quotient.

A later point of the same structure re-uses the last partition only after checking in
a few vector passes that it is that point's own: members agree with their
representative, and no two blocks have equal signatures (then, by induction on the
levels, equal recursive signatures and equal blocks coincide). So each point's
quotient, and every value a sweep prints, depends on that point alone, not on which
points a worker checked before.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from veribattery._sparse import csr_sharing
from veribattery._types import IntArray
from veribattery.explore.dtmc import DTMC, RewardVectors
from veribattery.explore.reuse.rounds import (
    IndexArray,
    Levels,
    Round,
    earlier_round,
    make_round,
    probability_bits,
    quotient_plan,
    round_holds,
    shared_successors,
    twin_seed_hashes,
)

__all__ = ["Lumper", "Partition", "dtmc_seeds", "partition"]

#: A quotient with more blocks than this fraction of the states is not used (checking
#: on it would save less than making it costs).
WORTH_FRACTION = 0.8
#: Rounds of splitting successors that share a block before giving up.
MAX_ROUNDS = 8
#: Partitions a :class:`Lumper` keeps for the points after (each is checked in turn).
PARTITIONS_KEPT = 3


def dtmc_seeds(dtmc: DTMC, variables: Sequence[str]) -> IntArray:
    """What bisimilar states must share, one int64 row per kind, one column per state:
    the labels (packed into bits), every reward structure's state and transition
    rewards (their float64 bits) and the values of *variables*."""
    n = dtmc.num_states
    names = sorted(dtmc.labels)
    columns = []
    for first in range(0, len(names), 63):  # 63 labels to a column
        packed = np.zeros(n, dtype=np.int64)
        for bit, name in enumerate(names[first:first + 63]):
            packed |= dtmc.labels[name].astype(np.int64) << bit
        columns.append(packed)
    for structure in dtmc.rewards:
        for part in (structure.state, structure.transition):
            values = np.ascontiguousarray(np.broadcast_to(part, (n,)), dtype=np.float64)
            columns.append(values.view(np.int64))
    columns += [dtmc.column(name).astype(np.int64) for name in sorted(set(variables))]
    return np.stack(columns) if columns else np.zeros((0, n), dtype=np.int64)


@dataclass(frozen=True, slots=True)
class Partition:
    """A stable partition of one structure's states at one point (module docstring).

    :param indptr: the structure's row pointers (later points must share the object).
    :param indices: its column indices (likewise).
    :param rounds: the partitions of the rounds, the last one without two successors of
        a state in one block; empty when there is no quotient (a cycle, no settling).
    :param q_gather: per quotient entry, its position in ``P.data``.
    :param q_indices: the quotient's column indices (sorted within rows).
    :param q_indptr: the quotient's row pointers.
    :param seeds: the seeds it was made with (a later point with the same seeds needs
        only its probabilities checked).
    :param sources: the arrays the seeds were made from (labels, rewards, state table):
        a point of a re-used structure that shares every one of them (the re-evaluation
        takes them over when they do not change) has these seeds, unmade.
    """

    indptr: IntArray
    indices: IntArray
    rounds: tuple[Round, ...]
    q_gather: IntArray
    q_indices: IndexArray
    q_indptr: IndexArray
    seeds: IntArray
    sources: tuple[object, ...] = ()

    @property
    def blocks(self) -> int:
        """The number of blocks (0 when there is no quotient)."""
        return self.rounds[-1].blocks if self.rounds else 0

    def worth(self, states: int) -> bool:
        """Whether the quotient is small enough to be worth checking on."""
        return bool(self.rounds) and self.blocks <= WORTH_FRACTION * states

    def fits(self, P: sp.csr_matrix) -> bool:
        """Whether *P* has this partition's pattern arrays (the very same objects)."""
        return P.indptr is self.indptr and P.indices is self.indices

    def holds(self, P: sp.csr_matrix, seeds: IntArray) -> bool:
        """Whether this is also the partition of *P*'s values and *seeds*, round by round
        (a chain with a cycle has none at any point: a property of its pattern)."""
        bits = probability_bits(P)
        indptr = np.asarray(self.indptr, dtype=np.int64)
        same = seeds is self.seeds or (
            seeds.shape == self.seeds.shape and bool(np.array_equal(seeds, self.seeds)))
        # The last round first: the earlier ones check only its representatives.
        return all(round_holds(found, indptr, bits, (seeds, same))
                   for found in reversed(self.rounds))

    def quotient(self, dtmc: DTMC, parts: dict[str, Any] | None = None) -> DTMC:
        """The quotient chain of *dtmc* (a point where this partition :meth:`holds`):
        a representative's variables, labels and rewards for each block (*parts*, those
        of :meth:`parts` of a DTMC that shares them, if given)."""
        last = self.rounds[-1]
        size = last.blocks
        data = np.take(np.asarray(dtmc.transitions.data, dtype=np.float64), self.q_gather)
        # The same index arrays at every point: the checker's pattern memos know them.
        transitions = csr_sharing(data, self.q_indices, self.q_indptr, (size, size))
        return replace(dtmc, transitions=transitions, **(parts or self.parts(dtmc)))

    def parts(self, dtmc: DTMC) -> dict[str, Any]:
        """The quotient's fields but its transitions: states, initial, labels, rewards."""
        last = self.rounds[-1]
        rep = last.representative
        rewards = tuple(RewardVectors(r.name, np.asarray(r.state)[rep],
                                      np.asarray(r.transition)[rep]) for r in dtmc.rewards)
        return {"states": np.take(dtmc.states, rep, axis=0), "initial": last.block[dtmc.initial],
                "labels": {name: mask[rep] for name, mask in dtmc.labels.items()},
                "rewards": rewards}


def _seed_sources(dtmc: DTMC, variables: Sequence[str]) -> tuple[object, ...]:
    """The arrays :func:`dtmc_seeds` reads (compared by identity), then the variables."""
    parts: list[object] = [dtmc.labels[name] for name in sorted(dtmc.labels)]
    parts += [part for r in dtmc.rewards for part in (r.state, r.transition)]
    return (*parts, dtmc.states, tuple(sorted(set(variables))))


def _same_sources(one: tuple[object, ...], other: tuple[object, ...]) -> bool:
    return (len(one) == len(other) and bool(one) and one[-1] == other[-1]
            and all(a is b for a, b in zip(one[:-1], other[:-1], strict=True)))


def partition(dtmc: DTMC, seeds: IntArray, sources: tuple[object, ...] = ()) -> Partition:
    """The partition of *dtmc*'s states at its values (no rounds, hence no quotient, if
    it has a cycle, its matrix is not canonical, or splitting did not settle).

    :param sources: what *seeds* were made from (:func:`_seed_sources`), to recognise
        later points with the same seeds; empty: never.
    """
    P = dtmc.transitions
    levels = Levels.of(P) if P.has_canonical_format else None
    empty = np.zeros(0, dtype=np.int64)
    none = Partition(P.indptr, P.indices, (), empty, empty, empty, seeds)
    if levels is None:
        return none
    bits = probability_bits(P)
    tags = np.zeros(dtmc.num_states, dtype=np.int64)
    tags[dtmc.initial] = dtmc.initial + 1  # initial states are never merged
    rounds: list[Round] = []
    while len(rounds) < MAX_ROUNDS:
        found = make_round(P, levels, bits, seeds, tags)
        if found is None:
            return none
        rounds.append(found)
        split = shared_successors(P, found)
        if not split.size:
            rounds = [earlier_round(r, found, P.indptr) for r in rounds[:-1]] + [found]
            rounds = [replace(r, twin_seed_hash=twin_seed_hashes(r, seeds)) for r in rounds]
            return Partition(P.indptr, P.indices, tuple(rounds), *quotient_plan(P, found),
                             seeds, sources)
        tags = tags.copy()
        tags[split] = split + 1
    return none


class Lumper:
    """The quotients of successive DTMCs of one structure (a sweep's points).

    Each point's quotient is that of its own partition: a recent partition is re-used
    only where :meth:`Partition.holds`, and one is made afresh otherwise. A few are
    kept, so that after a point with coincidences of its own (``p_wsp_c = 0.5``, where
    ``p = 1 - p`` merges more states) the next point finds the usual one again.
    """

    def __init__(self) -> None:
        self._recent: list[Partition] = []
        #: The last quotient's fields but its transitions, with its partition and the
        #: DTMC's seed sources: a later point with the same ones takes them over (not
        #: the quotient itself, whose solver memos would outlive their point).
        self._made: tuple[Partition, tuple[object, ...], dict[str, Any]] | None = None

    @property
    def _last(self) -> Partition | None:
        return self._recent[0] if self._recent else None

    def quotient(self, dtmc: DTMC, variables: Sequence[str]) -> DTMC | None:
        """The quotient of *dtmc* respecting its labels, rewards and *variables*, or
        None when there is none worth checking on (a cycle, too few states merged)."""
        sources = _seed_sources(dtmc, variables)
        found = self._partition(dtmc, variables, sources)
        if not found.worth(dtmc.num_states):
            return None
        made = self._made
        if made and made[0] is found and _same_sources(sources, made[1]):
            parts = made[2]
        else:
            parts = found.parts(dtmc)
            self._made = (found, sources, parts)
        return found.quotient(dtmc, parts)

    def _partition(self, dtmc: DTMC, variables: Sequence[str],
                   sources: tuple[object, ...]) -> Partition:
        """*dtmc*'s partition: a recent one that holds there, else a new one (first)."""
        P = dtmc.transitions
        self._recent = [kept for kept in self._recent if kept.fits(P)]
        # A kept partition's seeds when *dtmc* shares their sources (arrays are never
        # changed in place once a DTMC is built), else made once.
        seeds = next((kept.seeds for kept in self._recent
                      if _same_sources(sources, kept.sources)), None)
        if seeds is None:
            seeds = dtmc_seeds(dtmc, variables)
        for at, found in enumerate(self._recent):
            if found.holds(P, seeds):
                self._recent.insert(0, self._recent.pop(at))  # (by position: records
                return found  # compare their arrays, not their identity)
        found = partition(dtmc, seeds, sources)
        self._recent = [found, *self._recent][:PARTITIONS_KEPT]
        return found
