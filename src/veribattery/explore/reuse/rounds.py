"""The rounds of a lumping partition: made level by level from 64-bit signature hashes,
checked exactly, and re-checked at later points of the same structure.

A :class:`Round` is one partition of an acyclic chain's states with the index arrays
that check it again at another point (see :mod:`.lumping` for why rounds exist and
what makes a partition exact).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, cast

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from veribattery._types import IntArray
from veribattery._unique import distinct

__all__ = [
    "SALTS",
    "HashArray",
    "IndexArray",
    "Levels",
    "Round",
    "earlier_round",
    "make_round",
    "probability_bits",
    "quotient_plan",
    "round_holds",
    "shared_successors",
    "twin_seed_hashes",
]

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


def _ranges(starts: npt.NDArray[np.integer], lengths: npt.NDArray[np.integer]) -> IntArray:
    """The concatenated ranges ``starts[i] .. starts[i] + lengths[i]``."""
    lengths = np.asarray(lengths, dtype=np.int64)
    offsets = np.repeat(np.asarray(starts, dtype=np.int64) - (np.cumsum(lengths) - lengths),
                        lengths)
    return offsets + np.arange(int(lengths.sum()), dtype=np.int64)


@dataclass(frozen=True, slots=True)
class Round:
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
    #: earlier round checks only the last round's representatives (:func:`earlier_round`).
    members: IntArray | None = None
    member_entries: IntArray | None = None
    member_rep_entries: IntArray | None = None
    #: The twins' seeds and tags hashed, at the point the partition was made.
    twin_seed_hash: HashArray | None = None

    @property
    def blocks(self) -> int:
        return int(self.representative.size)


def probability_bits(P: sp.csr_matrix) -> IntArray:
    return np.ascontiguousarray(P.data, dtype=np.float64).view(np.int64)


@dataclass(frozen=True, slots=True)
class Levels:
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
    def of(cls, P: sp.csr_matrix) -> Levels | None:
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


def make_round(P: sp.csr_matrix, levels: Levels, bits: IntArray, seeds: IntArray,
          tags: IntArray) -> Round | None:
    """The partition by recursive signature, checked exactly (another salt after a
    clash; None if every salt clashed)."""
    for salt in SALTS:
        block = _groups(_signatures(P, levels, bits, (seeds, tags), salt))[0]
        found = _described(P, block, tags, bits)
        ordered = bits[found.order]
        if _members_agree(found, np.diff(P.indptr), ordered, seeds):
            return found
    return None


def _signatures(P: sp.csr_matrix, levels: Levels, bits: IntArray,
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


def _described(P: sp.csr_matrix, block: IntArray, tags: IntArray, bits: IntArray) -> Round:
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
    tie_rows = distinct(rows[1:][twin])
    return Round(block, tags, representative, order.astype(np.int64), keys,
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
        where = distinct(np.concatenate([tied, tied + 1]))
        order[where] = order[where][np.lexsort((bits[order[where]], keys[where], rows[where]))]
    return order


def _twins(indptr: IntArray, rep: IntArray, keys: IntArray,
           tags: IntArray) -> tuple[IntArray, HashArray, IntArray, HashArray, IntArray]:
    """The :class:`Round` fields of the blocks sharing a hash of (degree, tag, keys)."""
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


def _members_agree(found: Round, degree: IntArray, ordered: IntArray,
                   seeds: IntArray) -> bool:
    """Whether every state has its representative's degree, tag, keys (the structural
    part, the same at every point of the pattern), seed and bits."""
    own = found.representative[found.block]
    return _structure_agrees(found, degree, own) and _values_agree(found, ordered, seeds)


def _structure_agrees(found: Round, degree: IntArray, own: IntArray) -> bool:
    return bool(np.array_equal(degree, degree[own])
                and np.array_equal(found.tags, found.tags[own])
                and np.array_equal(found.keys, found.keys[found.rep_entry]))


def _values_agree(found: Round, ordered: IntArray, seeds: IntArray | None) -> bool:
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


def earlier_round(found: Round, last: Round, indptr: IntArray) -> Round:
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


def shared_successors(P: sp.csr_matrix, found: Round) -> IntArray:
    """The larger of every two successors of one state that share a block (to split):
    adjacent entries of one key among the round's tied rows (a row has one self-loop
    at most, so a key shared is a successor block's)."""
    ties, rows = found.ties, found.tie_rows
    keys = found.keys[ties]
    twin = np.flatnonzero((rows[1:] == rows[:-1]) & (keys[1:] == keys[:-1]))
    columns = P.indices[found.order[ties]]
    return distinct(np.maximum(columns[twin], columns[twin + 1])).astype(np.int64)


def quotient_plan(P: sp.csr_matrix, last: Round) -> tuple[IntArray, IndexArray, IndexArray]:
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


def round_holds(found: Round, indptr: IntArray, bits: IntArray,
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


def twin_seed_hashes(found: Round, seeds: IntArray) -> HashArray:
    return _row_hashes(np.take(seeds, found.twins, axis=1), found.tags[found.twins], SALTS[0])


def _blocks_differ(found: Round, indptr: IntArray, ordered: IntArray,
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
    hashes = known.copy() if same and known is not None else twin_seed_hashes(found, seeds)
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
