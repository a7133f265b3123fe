"""The set of known states: rows of variable values, numbered in insertion order.

Each state is encoded by mixed radix over its variables' ranges into one int64
*key* word (or a few words when the product of the ranges overflows 63 bits):
the variables packed into the fewest bits their ranges need. Only the keys are
stored, plus the rows added since the search last asked for rows (the next
frontier, which it asks for next); any other rows are decoded from the keys.
Keys live in an open-addressing hash table (linear probing) that is probed for a
whole batch at once, so lookups cost O(1) per state without a Python loop per
state, and unlike a sorted key array nothing is re-copied when a layer adds a few
states. A BFS layer is a batch of a few hundred rows, so the cost of a batch is its
count of numpy calls: the first slot of every key is read at once, the few keys
that meet another key there read a window of the next slots at once, and the new
keys are deduplicated and numbered by claiming their empty slots (no sort).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from veribattery._types import BoolArray, IntArray
from veribattery.explore.build.digits import decode, digit_groups

__all__ = ["StateStore", "narrowest_type", "radix_words"]

_WORD_LIMIT = 1 << 62  # largest product of ranges packed into one signed word
_QUADRUPLE_BELOW = 1 << 20  # slots of a table that grows fourfold, not twofold
# Operands as 0-d arrays: numpy 2 takes them in a ufunc for about half the cost of a
# Python or numpy scalar, and these operations run a few dozen times per BFS layer.
_GOLDEN = np.asarray(0x9E3779B97F4A7C15, dtype=np.uint64)  # Fibonacci hashing multiplier
_ZERO = np.asarray(0, dtype=np.int64)
_ONE = np.asarray(1, dtype=np.int64)
#: Slots read at once by a key whose first slot holds another key.
_WINDOW = 4
_STEPS = np.arange(1, _WINDOW + 1, dtype=np.int64)
#: States decoded at once into a narrow table (bounds the int64 rows of a block).
_DECODE_BLOCK = 1 << 16
#: Added to a batch position to mark a slot claimed during numbering (negative).
_MARK = np.asarray(np.iinfo(np.int32).min, dtype=np.int32)


def radix_words(lows: Sequence[int], highs: Sequence[int]) -> IntArray:
    """Multipliers ``(n_vars, n_words)`` packing variable offsets into key words.

    Variables are packed greedily in order; a variable whose range alone exceeds
    a word still gets a word of its own (its offset fits: ranges are int64).
    """
    words: list[dict[int, int]] = [{}]
    product = 1
    for i, (low, high) in enumerate(zip(lows, highs, strict=True)):
        size = high - low + 1
        if product * size > _WORD_LIMIT and words[-1]:
            words.append({})
            product = 1
        words[-1][i] = product
        product *= size
    multipliers = np.zeros((len(lows), len(words)), dtype=np.int64)
    for w, word in enumerate(words):
        for i, factor in word.items():
            multipliers[i, w] = factor
    return multipliers


class StateStore:
    """A growing, deduplicated table of states with O(1) batch lookup.

    :param lows: each variable's lower bound.
    :param highs: each variable's upper bound.
    """

    def __init__(self, lows: Sequence[int], highs: Sequence[int]) -> None:
        self._lows = np.asarray(lows, dtype=np.int64)
        self._sizes = np.asarray(highs, dtype=np.int64) - self._lows + 1
        self._multipliers = radix_words(lows, highs)
        self._groups = digit_groups(self._multipliers, self._lows.tolist(),
                                    self._sizes.tolist())
        # One key word (the usual case) is kept as a flat array: a comparison of flat
        # keys is one call, of key rows two or three.
        self._words = words = self._multipliers.shape[1]
        self._encoder = self._multipliers[:, 0].copy() if words == 1 else self._multipliers
        self._offset = self._lows @ self._encoder
        # Entry i + 1 holds state i's key; entry 0 is a sentinel that equals no key
        # (keys are offsets, never negative), read through the table's empty slots.
        # 1025 = 1024 states + the sentinel: doubled, it holds 2**k states + 1 exactly as
        # often as a power of two held 2**k states.
        self._keys = np.empty((1025,) if words == 1 else (1025, words), dtype=np.int64)
        self._keys[0] = -1
        # State index + 1 (0 = empty); int32 halves the table, the largest array here.
        self._resize(1 << 14)
        self.count = 0
        # Rows of states recent_start.. in order (the next frontier, and what is left of
        # the current one), in the narrowest type of the ranges: int64 rows of a model of
        # 32 variables take 256 bytes a state, two frontiers of crowds 5/20 220 MB.
        top = self._lows + self._sizes - 1
        self._row_type = narrowest_type(int(self._lows.min(initial=0)), int(top.max(initial=0)))
        self._recent: list[npt.NDArray[np.signedinteger[Any]]] = []
        self._recent_start = 0

    @property
    def states(self) -> IntArray:
        """The known states, one row each, in numbering order (decoded: a new array)."""
        return self._decode(0, self.count)

    @property
    def compact_states(self) -> npt.NDArray[np.signedinteger[Any]]:
        """:attr:`states` in the narrowest integer type (int8, int16, int32, else int64)
        that holds every variable's declared range, decoded a block at a time: the
        int64 table (8 bytes per state and variable) never exists at once."""
        table = np.empty((self.count, self._lows.size), dtype=self._row_type)
        for low in range(0, self.count, _DECODE_BLOCK):
            high = min(self.count, low + _DECODE_BLOCK)
            table[low:high] = self._decode(low, high)
        return table

    def rows(self, low: int, high: int) -> IntArray:
        """States ``low..high-1`` as rows of variable values (int64, a new array).

        Rows added since an earlier call are served as added (and forgotten once
        the search has moved past them); others are decoded from their keys.
        """
        self._forget_before(low)
        if low == self._recent_start and self._recent:
            rows = self._recent[0] if len(self._recent) == 1 else np.concatenate(self._recent)
            self._recent = [rows]
            if high <= self._recent_start + rows.shape[0]:
                return rows[: high - low].astype(np.int64)
        return self._decode(low, high)

    def rows_at(self, index: IntArray) -> IntArray:
        """The states numbered *index*, as rows (int64, decoded from their keys)."""
        keys = self._keys[np.asarray(index, dtype=np.int64) + 1]
        return decode(keys.reshape(index.size, self._words), self._groups, self._lows.size)

    def _forget_before(self, low: int) -> None:
        while self._recent and self._recent_start + self._recent[0].shape[0] <= low:
            self._recent_start += self._recent.pop(0).shape[0]
        if self._recent and self._recent_start < low:
            self._recent[0] = self._recent[0][low - self._recent_start :]
            self._recent_start = low

    def _decode(self, low: int, high: int) -> IntArray:
        keys = self._keys[low + 1 : high + 1].reshape(high - low, self._words)
        return decode(keys, self._groups, self._lows.size)

    def add(self, rows: IntArray) -> IntArray:
        """Index of each row, numbering unseen rows in order of first occurrence."""
        keys = self._encode(rows)
        index, slots = self._lookup(keys)
        missing = (index < _ZERO).nonzero()[0]
        if missing.size:
            self._number(rows, keys, index, slots, missing)
        return index

    def encode(self, rows: IntArray) -> IntArray:
        """Key words ``(n, n_words)`` of *rows*."""
        return self._encode(rows).reshape(rows.shape[0], self._words)

    def _encode(self, rows: IntArray) -> IntArray:
        """Keys of *rows*: flat ``(n,)`` for one word, else ``(n, n_words)``."""
        # rows @ M - lows @ M: the same words (exact in int64), one subtraction per key
        keys = rows @ self._encoder
        keys -= self._offset
        return keys

    # -- internals -----------------------------------------------------------

    def _lookup(self, keys: IntArray) -> tuple[IntArray, IntArray]:
        """Index of each key (-1 when absent) and the slot where its probe stopped.

        For an absent key that slot was empty: the key can be inserted there. The
        first slot is read for all keys at once; only the keys that find another
        key there (about one in ten at a load of at most 1/4) probe on.
        """
        slots = self._slots(keys)
        held = self._table[slots]
        # An empty slot holds 0, which reads the sentinel key: never equal.
        clash = self._differ(self._keys[held], keys)
        clash &= held != 0
        if np.count_nonzero(clash):
            where = clash.nonzero()[0]
            held[where], slots[where] = self._probe(keys[where], slots[where])
        return held - _ONE, slots  # int64: the 0-d operand is int64

    def _probe(self, keys: IntArray, slots: IntArray) -> tuple[np.ndarray, IntArray]:
        """What the linear probes after *slots* stop at (a match or an empty slot) and where.

        A round reads a window of the next ``_WINDOW`` slots of every key at once:
        at a load of at most 1/4 nearly every chain ends in the first window, so a
        batch's clashes cost one round of a few 2-D operations.
        """
        held, stop, going = self._window(keys, slots)
        while np.count_nonzero(going):  # rare: a chain longer than the window
            rest = going.nonzero()[0]
            slots = slots + _WINDOW  # each key's next window (those of the rest matter)
            slots &= self._mask
            held[rest], stop[rest], going[rest] = self._window(keys[rest], slots[rest])
        return held, stop

    def _window(self, keys: IntArray, slots: IntArray) -> tuple[np.ndarray, IntArray, BoolArray]:
        """One probing round: the entry and the slot where each probe stopped in the
        window after *slots*, and which probes went through the window without stopping.
        """
        window = slots[:, None] + _STEPS
        window &= self._mask
        held = self._table[window]
        stop = self._equal(self._keys[held], keys[:, None])
        stop |= held == 0
        pick = (np.arange(keys.shape[0]), stop.argmax(axis=1))
        return held[pick], window[pick], ~stop[pick]

    def _number(
        self, rows: IntArray, keys: IntArray, index: IntArray, slots: IntArray,
        missing: IntArray,
    ) -> None:
        """Number the absent keys at positions *missing* and insert them.

        Equal absent keys stop at the same empty slot, so each slot is claimed by
        the first position stopping there (``minimum.at`` of negative marks, read
        back); when every claimant's key equals its followers' (distinct new keys
        rarely stop at one slot), the claims are the first occurrences, numbered
        in order in the slots themselves. Otherwise the slots are cleared and the
        batch is deduplicated by sorting.
        """
        at = slots[missing]
        marks = missing.astype(np.int32)
        marks += _MARK
        np.minimum.at(self._table, at, marks)
        first = self._table[at] - _MARK  # int32: marks are positions - 2**31
        if np.count_nonzero(self._differ(keys[first], keys[missing])):
            self._table[at] = 0
            self._number_sorted(rows, keys, index, slots, missing)
            return
        claims = first == missing
        starts = missing[claims]
        numbers = np.arange(self.count + 1, self.count + 1 + starts.size, dtype=np.int32)
        self._table[at[claims]] = numbers
        index[missing] = self._table[at] - _ONE
        self._append(keys[starts], rows[starts])
        self._reserve_table()

    def _number_sorted(
        self, rows: IntArray, keys: IntArray, index: IntArray, slots: IntArray,
        missing: IntArray,
    ) -> None:
        """:meth:`_number` by sorting the absent keys (when distinct ones share a slot)."""
        first, inverse = _first_occurrences(keys[missing].reshape(missing.size, self._words))
        order = np.argsort(first, kind="stable")  # distinct keys by first occurrence
        numbers = np.empty(first.size, dtype=np.int64)
        numbers[order] = np.arange(self.count, self.count + first.size)
        index[missing] = numbers[inverse]
        starts = missing[first[order]]
        self._append(keys[starts], rows[starts])
        if not self._reserve_table():  # a rehash re-inserted everything already
            self._insert(numbers[order], slots[starts])

    def _append(self, keys: IntArray, rows: IntArray) -> None:
        """Store the keys of new states (numbered from ``count``) and keep their rows."""
        end = self.count + keys.shape[0]
        if end >= self._keys.shape[0]:
            self._keys = _grown(self._keys, max(end + 1, 2 * self._keys.shape[0] - 1))
        self._keys[self.count + 1 : end + 1] = keys
        if not self._recent:
            self._recent_start = self.count
        self._recent.append(rows.astype(self._row_type))
        self.count = end

    def _reserve_table(self) -> bool:
        """Keep the load factor at most 1/4 (short probe chains mean few rounds).

        A large table doubles (rather than growing fourfold) so that it never
        holds more than 8 slots per state: at 4 bytes a slot it would otherwise
        be the largest array of a search of millions of states. Below
        ``_QUADRUPLE_BELOW`` slots (4 MB) it grows fourfold: half the rebuilds,
        each of which re-inserts every known key, for at most 4 MB more.

        :returns: whether the table was rebuilt (with every known key inserted).
        """
        if 4 * self.count <= self._table.size:
            return False
        size = self._table.size
        while 4 * self.count > size:
            size *= 4 if size < _QUADRUPLE_BELOW else 2
        self._resize(size)
        everything = np.arange(self.count, dtype=np.int64)
        self._insert_probing(everything, self._slots(self._keys[1 : self.count + 1]))
        return True

    def _resize(self, size: int) -> None:
        """An empty table of *size* slots (a power of two), and its hashing constants."""
        self._table = np.zeros(size, dtype=np.int32)
        self._mask = np.asarray(size - 1, dtype=np.int64)
        self._shift = np.asarray(64 - size.bit_length() + 1, dtype=np.uint64)

    def _equal(self, a: IntArray, b: IntArray) -> np.ndarray:
        """Whether keys are equal (flat keys element-wise, key rows over their words)."""
        if self._keys.ndim == 1:
            return np.asarray(a == b)
        return np.asarray((a == b).all(axis=-1))

    def _differ(self, a: IntArray, b: IntArray) -> np.ndarray:
        """Whether keys differ (flat keys element-wise, key rows over their words)."""
        if self._keys.ndim == 1:
            return np.asarray(a != b)
        return np.asarray((a != b).any(axis=-1))

    def _slots(self, keys: IntArray) -> IntArray:
        if keys.ndim == 1:
            mixed = keys.view(np.uint64) * _GOLDEN
        else:
            mixed = keys[:, 0].view(np.uint64) * _GOLDEN
            for w in range(1, keys.shape[1]):
                mixed = (mixed ^ keys[:, w].view(np.uint64)) * _GOLDEN
        mixed >>= self._shift
        return mixed.view(np.int64)  # below 2**63 after the shift

    def _insert(self, index: IntArray, slots: IntArray) -> None:
        """Put the states *index* (absent, distinct) into the table at *slots*.

        Every slot must be empty; keys sharing one slot race, the write that sticks
        wins, and the others probe on.
        """
        self._table[slots] = index + 1
        lost = self._table[slots] != index + 1
        if np.count_nonzero(lost):
            self._insert_probing(index[lost], (slots[lost] + 1) & self._mask)

    def _insert_probing(self, index: IntArray, slots: IntArray) -> None:
        active = np.arange(index.size)
        while active.size:
            targets = slots[active]
            free = self._table[targets] == 0
            self._table[targets[free]] = index[active[free]] + 1
            placed = self._table[targets] == index[active] + 1
            active = active[~placed]
            slots[active] = (slots[active] + 1) & self._mask


def narrowest_type(low: int, high: int) -> type[np.signedinteger[Any]]:
    """The narrowest of int8, int16, int32 and int64 that holds *low* .. *high*."""
    for kind in (np.int8, np.int16, np.int32):
        limits = np.iinfo(kind)
        if limits.min <= low and high <= limits.max:
            return kind
    return np.int64


def _grown(array: IntArray, capacity: int) -> IntArray:
    bigger = np.empty((capacity, *array.shape[1:]), dtype=array.dtype)
    bigger[: array.shape[0]] = array
    return bigger


def _first_occurrences(keys: IntArray) -> tuple[IntArray, IntArray]:
    """Positions of the first occurrence of each distinct key row, and the inverse map."""
    if keys.shape[1] > 1:  # lexicographic order of whole rows
        order = np.lexsort(keys.T[::-1])
        ordered = keys[order]
        changed = np.any(ordered[1:] != ordered[:-1], axis=1)
    else:  # np.unique, minus its per-call overhead (this runs once per BFS layer)
        order = np.argsort(keys[:, 0], kind="stable")
        ordered = keys[order, 0]
        changed = ordered[1:] != ordered[:-1]
    starts = np.empty(keys.shape[0], dtype=bool)
    starts[:1] = True
    starts[1:] = changed
    inverse = np.empty(keys.shape[0], dtype=np.int64)
    inverse[order] = np.cumsum(starts) - _ONE
    return order[starts], inverse
