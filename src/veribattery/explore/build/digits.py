"""Key words decoded into rows of variable values, a group of variables at a time.

A key packs each variable's offset from its low bound as a mixed-radix digit (see
``store.radix_words``). Decoding digit by digit costs a division, a product and a
subtraction per variable and state: 1.2 s for the two million states of crowds
5/20 with 32 variables. Consecutive variables of one word whose ranges multiply to
at most ``GROUP_LIMIT`` form one wider digit, decoded with the same arithmetic
and then looked up in a table of its variables' values: crowds' 32 variables take
seven lookups. A variable wider than the limit is decoded alone, arithmetically.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from veribattery._types import IntArray

__all__ = ["GROUP_LIMIT", "DigitGroup", "decode", "digit_groups"]

#: Largest number of valuations of a group's variables (its table: a few kB per variable).
GROUP_LIMIT = 1 << 12


@dataclass(frozen=True, slots=True)
class DigitGroup:
    """Consecutive variables ``first..stop-1`` packed in key word *word*.

    :param divisor: the first variable's multiplier in the word.
    :param modulus: the product of the group's ranges, or None if no variable is
        packed above them (the quotient is the digit itself).
    :param table: ``(modulus, stop - first)``: each digit's values, lows included;
        None for a single variable wider than ``GROUP_LIMIT`` (then *low* is added).
    :param low: the single variable's low bound (0 with a table).
    """

    word: int
    first: int
    stop: int
    divisor: int
    modulus: int | None
    table: IntArray | None
    low: int


def digit_groups(multipliers: IntArray, lows: Sequence[int],
                 sizes: Sequence[int]) -> tuple[DigitGroup, ...]:
    """The groups of the variables packed by *multipliers* ``(n_vars, n_words)``."""
    word_of = multipliers.argmax(axis=1).tolist() if len(lows) else []
    groups: list[DigitGroup] = []
    first = 0
    while first < len(lows):
        stop, product = first + 1, sizes[first]
        while (stop < len(lows) and word_of[stop] == word_of[first]
               and product * sizes[stop] <= GROUP_LIMIT):
            product *= sizes[stop]
            stop += 1
        top = stop == len(lows) or word_of[stop] != word_of[first]
        word = word_of[first]
        groups.append(DigitGroup(
            word, first, stop, int(multipliers[first, word]), None if top else product,
            _table(lows[first:stop], sizes[first:stop]) if product <= GROUP_LIMIT else None,
            0 if product <= GROUP_LIMIT else lows[first],
        ))
        first = stop
    return tuple(groups)


def _table(lows: Sequence[int], sizes: Sequence[int]) -> IntArray:
    """Every digit's values: the first variable least significant, as in the key."""
    digit = np.arange(int(np.prod(sizes)), dtype=np.int64)
    table = np.empty((digit.size, len(sizes)), dtype=np.int64)
    for i, (low, size) in enumerate(zip(lows, sizes, strict=True)):
        digit, table[:, i] = np.divmod(digit, size)
        table[:, i] += low
    return table


def decode(keys: IntArray, groups: Sequence[DigitGroup], width: int) -> IntArray:
    """The rows ``(n, width)`` of the key words *keys* ``(n, n_words)``."""
    rows = np.empty((keys.shape[0], width), dtype=np.int64)
    for group in groups:
        digit = keys[:, group.word]
        if group.divisor != 1:
            digit = digit // group.divisor
        if group.modulus is not None:
            # numpy divides by a scalar with libdivide, but its % is a plain division
            digit = digit - digit // group.modulus * group.modulus
        if group.table is None:
            rows[:, group.first] = digit + group.low
        else:
            rows[:, group.first : group.stop] = group.table[digit]
    return rows
