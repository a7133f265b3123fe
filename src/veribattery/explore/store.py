"""The set of known states: rows of variable values, numbered in insertion order.

Each state is encoded by mixed radix over its variables' ranges into one int64
*key* word (or a few words when the product of the ranges overflows 63 bits):
the variables packed into the fewest bits their ranges need. Only the keys are
stored, plus the rows added since the search last asked for rows (the next
frontier, which it asks for next); any other rows are decoded from the keys.
Keys live in an open-addressing hash table that is probed for a whole batch at
once: each probing round is a handful of numpy operations over the rows still
unresolved, so lookups cost O(1) per state without a Python loop per state, and
unlike a sorted key array nothing is re-copied when a layer adds a few states.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from veribattery._types import IntArray

__all__ = ["StateStore", "radix_words"]

_WORD_LIMIT = 1 << 62  # largest product of ranges packed into one signed word
_QUADRUPLE_BELOW = 1 << 20  # slots of a table that grows fourfold, not twofold
# Operands as 0-d arrays: numpy 2 takes them in a ufunc for about half the cost of a
# Python or numpy scalar, and these operations run a few dozen times per BFS layer.
_GOLDEN = np.asarray(0x9E3779B97F4A7C15, dtype=np.uint64)  # Fibonacci hashing multiplier
_ZERO = np.asarray(0, dtype=np.int64)
_ONE = np.asarray(1, dtype=np.int64)


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
        self._word = self._multipliers.argmax(axis=1)  # each variable's key word
        self._offset = self._lows @ self._multipliers
        self._keys = np.empty((1024, self._multipliers.shape[1]), dtype=np.int64)
        # State index + 1 (0 = empty); int32 halves the table, the largest array here.
        self._table = np.zeros(1 << 14, dtype=np.int32)
        self.count = 0
        self._recent: list[IntArray] = []  # rows of states recent_start.. in order
        self._recent_start = 0

    @property
    def states(self) -> IntArray:
        """The known states, one row each, in numbering order (decoded: a new array)."""
        return self._decode(0, self.count)

    def rows(self, low: int, high: int) -> IntArray:
        """States ``low..high-1`` as rows of variable values.

        Rows added since an earlier call are served as added (and forgotten once
        the search has moved past them); others are decoded from their keys.
        """
        self._forget_before(low)
        if low == self._recent_start and self._recent:
            rows = self._recent[0] if len(self._recent) == 1 else np.concatenate(self._recent)
            self._recent = [rows]
            if high <= self._recent_start + rows.shape[0]:
                return rows[: high - low]
        return self._decode(low, high)

    def _forget_before(self, low: int) -> None:
        while self._recent and self._recent_start + self._recent[0].shape[0] <= low:
            self._recent_start += self._recent.pop(0).shape[0]
        if self._recent and self._recent_start < low:
            self._recent[0] = self._recent[0][low - self._recent_start :]
            self._recent_start = low

    def _decode(self, low: int, high: int) -> IntArray:
        keys = self._keys[low:high]
        rows = np.empty((keys.shape[0], self._lows.size), dtype=np.int64)
        for i, (word, size) in enumerate(zip(self._word, self._sizes, strict=True)):
            column = keys[:, word] // self._multipliers[i, word] if i else keys[:, word].copy()
            if i + 1 < self._lows.size and self._word[i + 1] == word:
                column %= size  # variables packed above this one are still in the word
            rows[:, i] = column
        rows += self._lows
        return rows

    def add(self, rows: IntArray) -> IntArray:
        """Index of each row, numbering unseen rows in order of first occurrence."""
        keys = self.encode(rows)
        first, inverse = _first_occurrences(keys)
        unique_keys = keys[first]
        index, slots = self._lookup(unique_keys)
        new = np.flatnonzero(index < _ZERO)
        if new.size == 0:  # nothing to number, append or insert
            return index[inverse]
        new = new[np.argsort(first[new], kind="stable")]
        index[new] = np.arange(self.count, self.count + new.size)
        self._append(unique_keys[new])
        if new.size:
            if not self._recent:
                self._recent_start = self.count - new.size
            self._recent.append(rows[first[new]])
        if not self._reserve_table():  # a rehash re-inserted everything already
            self._insert(index[new], slots[new])
        return index[inverse]

    def encode(self, rows: IntArray) -> IntArray:
        """Key words ``(n, n_words)`` of *rows*."""
        # rows @ M - lows @ M: the same words (exact in int64), one subtraction per key
        keys = rows @ self._multipliers
        keys -= self._offset
        return keys

    # -- internals -----------------------------------------------------------

    def _append(self, keys: IntArray) -> None:
        end = self.count + keys.shape[0]
        if end > self._keys.shape[0]:
            self._keys = _grown(self._keys, max(end, 2 * self._keys.shape[0]))
        self._keys[self.count : end] = keys
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
        self._table = np.zeros(size, dtype=np.int32)
        everything = np.arange(self.count, dtype=np.int64)
        self._insert_probing(everything, self._slots(self._keys[: self.count]))
        return True

    def _slots(self, keys: IntArray) -> IntArray:
        bits = np.asarray(64 - int(self._table.size).bit_length() + 1, dtype=np.uint64)
        mixed = keys[:, 0].view(np.uint64) * _GOLDEN
        for w in range(1, keys.shape[1]):
            mixed = (mixed ^ keys[:, w].view(np.uint64)) * _GOLDEN
        mixed >>= bits
        return mixed.view(np.int64)  # below 2**63 after the shift

    def _lookup(self, keys: IntArray) -> tuple[IntArray, IntArray]:
        """Index of each key (-1 when absent) and the slot where its probe stopped.

        For an absent key that slot was empty: the key can be inserted there. The
        first probe is done for all keys at once; only the (few, at load <= 1/4)
        keys that hit another key's slot go through the probing loop.
        """
        slots = self._slots(keys)
        index = self._table[slots].astype(np.int64)
        index -= _ONE
        # An empty slot gives index -1: the comparison reads the last key row
        # (garbage) and its result is masked by ``index >= 0``.
        clash = index >= _ZERO
        clash &= ~_rows_equal(self._keys[index], keys)
        if np.count_nonzero(clash):
            where = np.flatnonzero(clash)
            mask = self._table.size - 1
            index[where], slots[where] = self._probe(keys[where], (slots[where] + 1) & mask)
        return index, slots

    def _probe(self, keys: IntArray, slots: IntArray) -> tuple[IntArray, IntArray]:
        """Linear probing from *slots*, one slot a round for all the unresolved keys.

        Only keys whose first slot held another key come here (a few dozen per
        batch at a load of at most 1/4), and their chains are short: a round of
        one-dimensional operations over them costs less than a window of slots.
        """
        mask = np.asarray(self._table.size - 1, dtype=np.int64)
        index = np.full(keys.shape[0], -1, dtype=np.int64)
        active = np.arange(keys.shape[0])
        at, wanted = slots.copy(), keys
        while active.size:
            held = self._table[at].astype(np.int64)
            held -= _ONE  # -1 where empty: the key row it reads is masked below
            empty = held < _ZERO
            match = _rows_equal(self._keys[held], wanted)
            match &= ~empty
            ended = match | empty
            found = np.flatnonzero(match)
            index[active[found]] = held[found]
            stop = np.flatnonzero(ended)
            slots[active[stop]] = at[stop]
            going = np.flatnonzero(~ended)
            active, wanted = active[going], wanted[going]
            at = at[going] + _ONE
            at &= mask
        return index, slots

    def _insert(self, index: IntArray, slots: IntArray) -> None:
        """Put the states *index* (absent, distinct) into the table at *slots*.

        Every slot must be empty; keys sharing one slot race, the write that sticks
        wins, and the others probe on.
        """
        self._table[slots] = index + 1
        lost = self._table[slots] != index + 1
        if np.count_nonzero(lost):
            mask = self._table.size - 1
            self._insert_probing(index[lost], (slots[lost] + 1) & mask)

    def _insert_probing(self, index: IntArray, slots: IntArray) -> None:
        mask = self._table.size - 1
        active = np.arange(index.size)
        while active.size:
            targets = slots[active]
            free = self._table[targets] == 0
            self._table[targets[free]] = index[active[free]] + 1
            placed = self._table[targets] == index[active] + 1
            active = active[~placed]
            slots[active] = (slots[active] + 1) & mask


def _grown(array: IntArray, capacity: int) -> IntArray:
    bigger = np.empty((capacity, array.shape[1]), dtype=array.dtype)
    bigger[: array.shape[0]] = array
    return bigger


def _rows_equal(a: IntArray, b: IntArray) -> np.ndarray:
    """Whether key rows are equal, over the last axis (the words)."""
    if a.shape[-1] == 1:
        return np.asarray(a[..., 0] == b[..., 0])
    return np.asarray((a == b).all(axis=-1))


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
