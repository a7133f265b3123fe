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
from typing import Any, cast

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from veribattery._sparse import csr_sharing
from veribattery._types import IntArray
from veribattery.explore.dtmc import DTMC, RewardVectors

__all__ = ["Lumper", "Partition", "dtmc_seeds", "partition"]

#: A quotient with more blocks than this fraction of the states is not used (checking
#: on it would save less than making it costs).
WORTH_FRACTION = 0.8
#: Rounds of splitting successors that share a block before giving up.
MAX_ROUNDS = 8
#: Partitions a :class:`Lumper` keeps for the points after (each is checked in turn).
PARTITIONS_KEPT = 3
#: Hash salts tried in turn should a clash merge states that differ.
SALTS = (0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9)

_U64 = np.uint64
HashArray = npt.NDArray[np.uint64]
IndexArray = npt.NDArray[np.signedinteger[Any]]
#: The hash standing for "this state itself" (a self-loop's successor).
_SELF = _U64(0x5851F42D4C957F2D)


def _mix(x: npt.NDArray[np.integer]) -> HashArray:
    """SplitMix64's finaliser, elementwise (uint64 arithmetic wraps, as it should)."""
    return _mixed(np.asarray(x).astype(_U64, copy=True))


def _mixed(y: HashArray) -> HashArray:
    """:func:`_mix` in *y*'s own memory."""
    y ^= y >> _U64(30)
    y *= _U64(0xBF58476D1CE4E5B9)
    y ^= y >> _U64(27)
    y *= _U64(0x94D049BB133111EB)
    y ^= y >> _U64(31)
    return y


def _groups(values: npt.NDArray[np.integer]) -> tuple[IntArray, IntArray]:
    """Group ids of *values* (numbered in value order) and each group's size:
    ``np.unique``'s inverse and counts (which it makes several times more slowly)."""
    order = np.argsort(values)
    ranked = values[order]
    new = np.concatenate([[False], ranked[1:] != ranked[:-1]])
    ids = np.empty(values.size, dtype=np.int64)
    ids[order] = np.cumsum(new)
    starts = np.flatnonzero(new)
    return ids, np.diff(np.concatenate([[0], starts, [values.size]]))


def _firsts(block: IntArray, count: int) -> IntArray:
    """The smallest state of each of *count* blocks (later writes win: go backwards)."""
    first = np.empty(count, dtype=np.int64)
    first[block[::-1]] = np.arange(block.size - 1, -1, -1, dtype=np.int64)
    return first


def _distinct(values: npt.NDArray[np.integer]) -> IntArray:
    """The distinct *values*, ascending."""
    ranked = np.sort(values)
    return ranked[np.concatenate([[True], ranked[1:] != ranked[:-1]])] if ranked.size else ranked


def _ranges(starts: npt.NDArray[np.integer], lengths: npt.NDArray[np.integer]) -> IntArray:
    """The concatenated ranges ``starts[i] .. starts[i] + lengths[i]``."""
    lengths = np.asarray(lengths, dtype=np.int64)
    offsets = np.repeat(np.asarray(starts, dtype=np.int64) - (np.cumsum(lengths) - lengths),
                        lengths)
    return offsets + np.arange(int(lengths.sum()), dtype=np.int64)


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
class _Round:
    """One partition of the rounds, with the index arrays that check it at other points.

    :param block: each state's block.
    :param tags: per state, 0 or the unique tag that keeps it apart (initial and split
        states).
    :param representative: per block, its smallest state.
    :param order: the positions in ``P.data`` of all entries, sorted by (row, key, bits):
        each row's entries then lie where ``P``'s do (``indptr``).
    :param keys: per sorted entry, its successor's block, or -1 for a self-loop.
    :param rep_entry: per sorted entry, the sorted position of the representative's
        entry of the same rank.
    :param ties: sorted positions of the entries of rows with two entries of one key
        (their order by bits is taken again at each point), and each one's row.
    :param twins: the representatives of the blocks whose degree, tag and keys are
        not unique among blocks (only these can ever agree at another point), with
        their group's hash (*twin_group*), the sorted positions of their entries
        (*twin_entries*), each one's rank (shifted, to be hashed) and where each
        representative's entries end among them (*twin_ends*).
    """

    block: IntArray
    tags: IntArray
    representative: IntArray
    order: IntArray
    keys: IntArray
    rep_entry: IntArray
    ties: IntArray
    tie_rows: IntArray
    twins: IntArray
    twin_group: HashArray
    twin_entries: IntArray
    twin_ranks: HashArray
    twin_ends: IntArray
    #: The states checked against their representative (None: all), the sorted
    #: positions of their entries and of their representatives' matching entries: an
    #: earlier round checks only the last round's representatives (:func:`_earlier`).
    members: IntArray | None = None
    member_entries: IntArray | None = None
    member_rep_entries: IntArray | None = None
    #: The twins' seeds and tags hashed, at the point the partition was made.
    twin_seed_hash: HashArray | None = None

    @property
    def blocks(self) -> int:
        return int(self.representative.size)


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
    rounds: tuple[_Round, ...]
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
        bits = _bits(P)
        indptr = np.asarray(self.indptr, dtype=np.int64)
        same = seeds is self.seeds or (
            seeds.shape == self.seeds.shape and bool(np.array_equal(seeds, self.seeds)))
        # The last round first: the earlier ones check only its representatives.
        return all(_round_holds(found, indptr, bits, (seeds, same))
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


def _bits(P: sp.csr_matrix) -> IntArray:
    return np.ascontiguousarray(P.data, dtype=np.float64).view(np.int64)


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
    levels = _Levels.of(P) if P.has_canonical_format else None
    empty = np.zeros(0, dtype=np.int64)
    none = Partition(P.indptr, P.indices, (), empty, empty, empty, seeds)
    if levels is None:
        return none
    bits = _bits(P)
    tags = np.zeros(dtmc.num_states, dtype=np.int64)
    tags[dtmc.initial] = dtmc.initial + 1  # initial states are never merged
    rounds: list[_Round] = []
    while len(rounds) < MAX_ROUNDS:
        found = _made(P, levels, bits, seeds, tags)
        if found is None:
            return none
        rounds.append(found)
        split = _shared_successors(P, found)
        if not split.size:
            rounds = [_earlier(r, found, P.indptr) for r in rounds[:-1]] + [found]
            rounds = [replace(r, twin_seed_hash=_twin_seed_hash(r, seeds)) for r in rounds]
            return Partition(P.indptr, P.indices, tuple(rounds), *_quotient_plan(P, found),
                             seeds, sources)
        tags = tags.copy()
        tags[split] = split + 1
    return none


@dataclass(frozen=True, slots=True)
class _Levels:
    """The states by height (longest path to a state without other successors), and
    their entries in that order, so that each level is one slice.

    :param states: the states, level by level.
    :param state_bounds: where each level starts in *states* (and the end).
    :param entries: positions in ``P.data`` of the states' entries, in *states*' order.
    :param entry_bounds: where each level starts in *entries* (and the end).
    :param row_ends: per state of *states*, where its entries end within its level.
    """

    states: IntArray
    state_bounds: IntArray
    entries: IntArray
    entry_bounds: IntArray
    row_ends: IntArray

    @classmethod
    def of(cls, P: sp.csr_matrix) -> _Levels | None:
        """The levels of *P*'s graph; None if it has a cycle other than a self-loop."""
        n = P.shape[0]
        levels = _heights(P)  # (Kahn's algorithm never reaches a state on a cycle)
        if levels is None:
            return None
        states = np.concatenate(levels) if levels else np.zeros(0, dtype=np.int64)
        degree = np.diff(P.indptr)[states]
        sizes = np.array([level.size for level in levels], dtype=np.int64)
        state_bounds = np.concatenate([[0], np.cumsum(sizes)])
        ends = np.cumsum(degree)
        entry_bounds = np.concatenate([[0], ends[state_bounds[1:] - 1]]) if n else np.zeros(1)
        level_of = np.repeat(np.arange(sizes.size), sizes)
        return cls(states, state_bounds, _ranges(P.indptr[states], degree),
                   entry_bounds.astype(np.int64), ends - entry_bounds[level_of])


def _heights(P: sp.csr_matrix) -> list[IntArray] | None:
    """Kahn's algorithm from the states without other successors, level by level; None
    if some state is never reached (it lies on a cycle or leads into one)."""
    n = P.shape[0]
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(P.indptr))
    off = P.indices != rows
    remaining = np.bincount(rows[off], minlength=n)
    back = sp.csr_matrix((np.ones(int(off.sum()), dtype=np.int8),
                          (P.indices[off], rows[off])), shape=(n, n))  # predecessors
    levels, frontier, seen = [], np.flatnonzero(remaining == 0), 0
    while frontier.size:
        levels.append(frontier)
        seen += frontier.size
        starts = back.indptr[frontier]
        preds = back.indices[_ranges(starts, back.indptr[frontier + 1] - starts)]
        preds.sort()
        first = np.flatnonzero(np.concatenate([[preds.size > 0], preds[1:] != preds[:-1]]))
        found = preds[first]
        remaining[found] -= np.diff(np.append(first, preds.size))
        frontier = found[remaining[found] == 0]
    return levels if seen == n else None


def _made(P: sp.csr_matrix, levels: _Levels, bits: IntArray, seeds: IntArray,
          tags: IntArray) -> _Round | None:
    """The partition by recursive signature, checked exactly (another salt after a
    clash; None if every salt clashed)."""
    for salt in SALTS:
        block = _groups(_signatures(P, levels, bits, (seeds, tags), salt))[0]
        found = _described(P, block, tags, bits)
        ordered = bits[found.order]
        if _members_agree(found, np.diff(P.indptr), ordered, seeds):
            return found
    return None


def _signatures(P: sp.csr_matrix, levels: _Levels, bits: IntArray,
                seeds_and_tags: tuple[IntArray, IntArray], salt: int) -> HashArray:
    """Each state's recursive signature hash, level by level (an order-free sum over
    its entries, so that no sort is needed)."""
    seeds, tags = seeds_and_tags
    n = P.shape[0]
    degree = np.diff(P.indptr)
    own = (_row_hashes(seeds, tags, salt) + _mix(degree))[levels.states]
    # Signatures in level order, one more slot standing for "itself" (self-loops).
    signature = np.zeros(n + 1, dtype=_U64)
    signature[n] = _SELF
    position = np.empty(n, dtype=np.int64)
    position[levels.states] = np.arange(n, dtype=np.int64)
    columns = P.indices[levels.entries]
    successors = np.where(columns == np.repeat(levels.states, degree[levels.states]), n,
                          position[columns])
    # An entry adds its successor's signature times an odd number made from its bits:
    # signatures are mixed already, and a product keeps (t1, p), (t2, q) apart from
    # (t1, q), (t2, p) where a sum of xors would not.
    entry_bits = _mix(bits[levels.entries]) ^ _U64(salt)
    entry_bits |= _U64(1)
    bounds, entries, ends = levels.state_bounds, levels.entry_bounds, levels.row_ends
    starts = ends - degree[levels.states]
    for level in range(bounds.size - 1):
        lo, hi = entries[level], entries[level + 1]
        first, last = bounds[level], bounds[level + 1]
        successor = signature[successors[lo:hi]]
        successor *= entry_bits[lo:hi]
        total = np.zeros(hi - lo + 1, dtype=_U64)
        np.cumsum(successor, out=total[1:])
        mine = total[ends[first:last]]
        mine -= total[starts[first:last]]
        mine += own[first:last]
        mine ^= mine >> _U64(33)  # a shorter finaliser: clashes are caught exactly anyway
        mine *= _U64(0xFF51AFD7ED558CCD)
        mine ^= mine >> _U64(29)
        signature[first:last] = mine
    return signature[position]


def _row_hashes(seeds: IntArray, tags: IntArray, salt: int) -> HashArray:
    hashes = _mix(tags.view(_U64) + _U64(salt))
    for j, row in enumerate(seeds):
        hashes = _mix(hashes ^ _mix(row.view(_U64) + _U64(j + 1)))
    return hashes


def _described(P: sp.csr_matrix, block: IntArray, tags: IntArray, bits: IntArray) -> _Round:
    """*block* with the index arrays that check it, here and at other points."""
    n = P.shape[0]
    degree = np.diff(P.indptr)
    rows = np.repeat(np.arange(n, dtype=np.int64), degree)
    keys = np.where(P.indices == rows, -1, block[P.indices])
    count = int(block.max(initial=-1)) + 1
    order = _entry_order(rows, keys, bits, count + 1)
    keys = keys[order]
    representative = _firsts(block, count)
    ranks = np.arange(rows.size, dtype=np.int64) - np.repeat(P.indptr[:-1], degree)
    rep_entry = np.repeat(P.indptr[representative[block]], degree) + ranks
    twin = (rows[1:] == rows[:-1]) & (keys[1:] == keys[:-1])
    tie_rows = _distinct(rows[1:][twin])
    return _Round(block, tags, representative, order.astype(np.int64), keys,
                  rep_entry.astype(np.int64), _ranges(P.indptr[tie_rows], degree[tie_rows]),
                  np.repeat(tie_rows, degree[tie_rows]),
                  *_twins(np.asarray(P.indptr, dtype=np.int64), representative, keys, tags))


def _entry_order(rows: IntArray, keys: IntArray, bits: IntArray, width: int) -> IntArray:
    """``np.lexsort((bits, keys, rows))`` for rows already ascending: one stable sort of
    (row, key) and, for the rows with two entries of one key, a lexsort of those."""
    order = np.argsort(rows * width + (keys + 1), kind="stable")
    rows, keys = rows[order], keys[order]
    tied = np.flatnonzero((rows[1:] == rows[:-1]) & (keys[1:] == keys[:-1]))
    if tied.size:
        where = _distinct(np.concatenate([tied, tied + 1]))
        order[where] = order[where][np.lexsort((bits[order[where]], keys[where], rows[where]))]
    return order


def _twins(indptr: IntArray, rep: IntArray, keys: IntArray,
           tags: IntArray) -> tuple[IntArray, HashArray, IntArray, HashArray, IntArray]:
    """The :class:`_Round` fields of the blocks sharing a hash of (degree, tag, keys)."""
    zero = np.zeros((0, rep.size), dtype=np.int64)
    hashes = _block_hashes(indptr, rep, (keys, np.zeros_like(keys)), (zero, tags[rep]))
    groups, counts = _groups(hashes)
    shared = np.flatnonzero(counts[groups] > 1)
    twins = rep[shared]
    degree = indptr[twins + 1] - indptr[twins]
    entries = _ranges(indptr[twins], degree)
    ranks = (entries - np.repeat(indptr[twins], degree)).astype(_U64) << _U64(40)
    return twins, _mix(hashes[shared]), entries, ranks, np.cumsum(degree)


def _block_hashes(indptr: IntArray, rep: IntArray, entries: tuple[IntArray, IntArray],
                  own: tuple[IntArray, IntArray]) -> HashArray:
    """A hash per block of its representative's seed, tag, degree and sorted entries
    (*entries*: keys and bits, in sorted order; *own*: the representatives' seeds, tags)."""
    degree = (indptr[1:] - indptr[:-1])[rep]
    positions = _ranges(indptr[rep], degree)
    keys, values = entries[0][positions], entries[1][positions]
    ranks = (positions - np.repeat(indptr[rep], degree)).astype(_U64)
    entry = _mix(_mix(keys.view(_U64)) ^ values.view(_U64) ^ (ranks << _U64(40)))
    total = np.concatenate([np.zeros(1, dtype=_U64), np.cumsum(entry, dtype=_U64)])
    local = np.concatenate([[0], np.cumsum(degree)])
    hashes = _row_hashes(*own, SALTS[0])
    hashes += _mix(degree)
    hashes += total[local[1:]] - total[local[:-1]]
    return hashes


def _members_agree(found: _Round, degree: IntArray, ordered: IntArray,
                   seeds: IntArray) -> bool:
    """Whether every state has its representative's degree, tag, keys (the structural
    part, the same at every point of the pattern), seed and bits."""
    own = found.representative[found.block]
    return _structure_agrees(found, degree, own) and _values_agree(found, ordered, seeds)


def _structure_agrees(found: _Round, degree: IntArray, own: IntArray) -> bool:
    return bool(np.array_equal(degree, degree[own])
                and np.array_equal(found.tags, found.tags[own])
                and np.array_equal(found.keys, found.keys[found.rep_entry]))


def _values_agree(found: _Round, ordered: IntArray, seeds: IntArray | None) -> bool:
    """Whether the members have their representatives' seeds (None: the seeds the
    partition was made with, known to agree) and bits."""
    members = found.members
    if seeds is not None:
        own = found.representative[found.block if members is None else found.block[members]]
        for row in seeds:
            if row.min() != row.max():  # (a seed equal in every state needs no gather)
                mine = row if members is None else np.take(row, members)
                if not np.array_equal(mine, np.take(row, own)):
                    return False
    if found.member_entries is None or found.member_rep_entries is None:
        return bool(np.array_equal(ordered, np.take(ordered, found.rep_entry)))
    return bool(np.array_equal(np.take(ordered, found.member_entries),
                               np.take(ordered, found.member_rep_entries)))


def _earlier(found: _Round, last: _Round, indptr: IntArray) -> _Round:
    """*found* (a round before *last*) checking only *last*'s representatives.

    The last round refines every earlier one (its tags only add, its keys refine
    theirs), so a state that agrees with its last representative there has the same
    seed and multiset of (earlier block, bits) as that representative: once the last
    round holds, an earlier one holds if those representatives agree with theirs.
    """
    members = last.representative
    entries = _ranges(indptr[members], indptr[members + 1] - indptr[members])
    return replace(found, members=members, member_entries=entries,
                   member_rep_entries=found.rep_entry[entries])


def _shared_successors(P: sp.csr_matrix, found: _Round) -> IntArray:
    """The larger of every two successors of one state that share a block (to split):
    adjacent entries of one key among the round's tied rows (a row has one self-loop
    at most, so a key shared is a successor block's)."""
    ties, rows = found.ties, found.tie_rows
    keys = found.keys[ties]
    twin = np.flatnonzero((rows[1:] == rows[:-1]) & (keys[1:] == keys[:-1]))
    columns = P.indices[found.order[ties]]
    return _distinct(np.maximum(columns[twin], columns[twin + 1])).astype(np.int64)


def _quotient_plan(P: sp.csr_matrix, last: _Round) -> tuple[IntArray, IndexArray, IndexArray]:
    """Where each quotient entry comes from (a representative's entry), its column,
    and the quotient's row pointers (columns sorted within rows; int32 where they fit,
    as scipy would make them)."""
    rep = last.representative
    degree = np.diff(P.indptr)[rep]
    positions = _ranges(P.indptr[rep], degree)
    rows = np.repeat(np.arange(rep.size, dtype=np.int64), degree)
    columns = last.block[P.indices[positions]]
    order = np.argsort(rows * rep.size + columns, kind="stable")  # (rows ascending)
    index = np.int32 if max(positions.size, rep.size) < 2**31 - 1 else np.int64
    indptr = np.concatenate([[0], np.cumsum(degree)]).astype(index)
    return positions[order], cast(IndexArray, columns[order].astype(index)), cast(
        IndexArray, indptr)


def _round_holds(found: _Round, indptr: IntArray, bits: IntArray,
                 seeds: tuple[IntArray, bool]) -> bool:
    """Whether *found* is the partition at these values and seeds (and whether those are
    the ones it was made with): every state agrees with its representative, and no two
    blocks agree."""
    ordered = bits[found.order]
    if found.ties.size:  # rows with two entries of one key: order those by bits again
        tied = ordered[found.ties]
        ordered[found.ties] = tied[np.lexsort((tied, found.keys[found.ties], found.tie_rows))]
    return (_values_agree(found, ordered, None if seeds[1] else seeds[0])
            and _blocks_differ(found, indptr, ordered, seeds))


def _twin_seed_hash(found: _Round, seeds: IntArray) -> HashArray:
    return _row_hashes(np.take(seeds, found.twins, axis=1), found.tags[found.twins], SALTS[0])


def _blocks_differ(found: _Round, indptr: IntArray, ordered: IntArray,
                   given: tuple[IntArray, bool]) -> bool:
    """Whether the blocks' signatures (their representatives') are pairwise different.

    Only blocks of one twin group can agree (the others differ in degree, tag or
    keys): their seeds and bits are hashed with the group's, and compared exactly
    where two hashes are equal.
    """
    twins = found.twins
    if not twins.size:
        return True
    entry = _mix(ordered[found.twin_entries].view(_U64) ^ found.twin_ranks)
    total = np.concatenate([np.zeros(1, dtype=_U64), np.cumsum(entry, dtype=_U64)])
    seeds, same = given
    known = found.twin_seed_hash
    hashes = known.copy() if same and known is not None else _twin_seed_hash(found, seeds)
    hashes += total[found.twin_ends] - total[found.twin_ends - (indptr[twins + 1] - indptr[twins])]
    hashes ^= found.twin_group
    ranked = np.sort(hashes)
    if not np.any(ranked[1:] == ranked[:-1]):
        return True
    order = np.argsort(hashes, kind="stable")
    for i in np.flatnonzero(hashes[order][1:] == hashes[order][:-1]):
        a, b = twins[order[i]], twins[order[i + 1]]  # equal hashes: compare exactly
        if (found.tags[a] == found.tags[b] and np.array_equal(seeds[:, a], seeds[:, b])
                and np.array_equal(found.keys[indptr[a]:indptr[a + 1]],
                                   found.keys[indptr[b]:indptr[b + 1]])
                and np.array_equal(ordered[indptr[a]:indptr[a + 1]],
                                   ordered[indptr[b]:indptr[b + 1]])):
            return False
    return True


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
