"""The choice matrix laid out for many Bellman rounds: an optimum without ``reduceat``.

A round takes, per state, the best image of its choices. ``np.maximum.reduceat``
does that over the rows grouped by state, but pays about 10 ns per state: on
958,894 states of 3,080,702 choices, 13 ms per call, three calls a round, more than
the two products of the round together. :class:`ChoiceLevels` lays the rows out by
*level* instead: level *j* holds the *j*-th choice of every state that has more
than *j*, and the states are ordered by their number of choices, most first, so
that the states of every level are a prefix of that order. The optimum is then
one elementwise maximum per level over contiguous slices (about 2 ms there).
(:class:`~veribattery.checker.mdp.system.ClassRows` takes such maxima by gathering
each level's rows where they are stored, about 10 ms there; here the rows are moved
once, before the rounds.)

Values stay bit for bit what they were: each row keeps its stored entries in their
order, so every product sums the same terms in the same order, and a maximum does
not depend on the order it is taken in. Ties go to the first choice, as before.
A model whose states have very many choices (more than :data:`DEEPEST` levels)
keeps its own layout and ``reduceat`` (:meth:`ChoiceLevels.grouped`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray, RankArray
from veribattery.checker.mdp.model import MDP

__all__ = ["DEEPEST", "ChoiceLevels"]

_Array = TypeVar("_Array", FloatArray, BoolArray, IntArray, RankArray)

#: At most this many levels (choices of one state) are laid out; a Python step per
#: level and round costs a few microseconds. (Ranks among them fit an int8.)
DEEPEST = 64


@dataclass(frozen=True, slots=True)
class ChoiceLevels:
    """The rows of an MDP's choice matrix by level, its states by choices, most first.

    :param matrix: the choice matrix, rows in level order and columns in state order.
    :param order: per position, the state there (identity in the grouped layout).
    :param widths: per level, how many states have a choice there (a prefix of *order*).
    :param groups: the model's ``row_groups`` (for the grouped layout and the choices).
    :param leveled: whether the rows are by level (else grouped by state, as stored).
    """

    matrix: CsrMatrix
    order: IntArray
    widths: tuple[int, ...]
    groups: IntArray
    leveled: bool
    #: Per level, the last first: its number, its first row and its width.
    spans: tuple[tuple[int, int, int], ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        ends = np.cumsum(self.widths, dtype=np.int64).tolist()
        spans = [(level, end - width, width)
                 for level, (end, width) in enumerate(zip(ends, self.widths, strict=True))]
        object.__setattr__(self, "spans", tuple(reversed(spans)))

    @classmethod
    def of(cls, mdp: MDP) -> ChoiceLevels:
        """The level layout of *mdp*, or the grouped one where it has too many levels."""
        counts = np.diff(mdp.row_groups)
        if not mdp.num_states or int(counts.max()) > DEEPEST:
            return cls.grouped(mdp)
        order = np.argsort(-counts, kind="stable")
        ranked = counts[order]
        widths = tuple(int(np.count_nonzero(ranked > j)) for j in range(int(ranked[0])))
        rows = _laid_rows(mdp.row_groups, order, widths)
        return cls(_rows_taken(mdp.transitions, rows, order), order, widths, mdp.row_groups,
                   True)

    @classmethod
    def grouped(cls, mdp: MDP) -> ChoiceLevels:
        """The model's own layout: rows grouped by state, reduced by ``reduceat``."""
        return cls(mdp.transitions, np.arange(mdp.num_states), (), mdp.row_groups, False)

    def states(self, values: _Array) -> _Array:
        """Per-state *values* in this layout's order."""
        return values[self.order] if self.leveled else values

    def choices(self, values: _Array) -> _Array:
        """Per-choice *values* in this layout's row order."""
        return values[_laid_rows(self.groups, self.order, self.widths)] if self.leveled else values

    def restored(self, values: _Array) -> _Array:
        """Per-state *values* of this layout's order back in the model's order."""
        if not self.leveled:
            return values
        back = np.empty_like(values)
        back[self.order] = values
        return back

    def optimum(self, images: FloatArray, reduce: np.ufunc) -> FloatArray:
        """Per state (this layout's order), *reduce* of its choices' *images*."""
        if not self.leveled:
            return np.asarray(reduce.reduceat(images, self.groups[:-1]), dtype=images.dtype)
        best = images[: self.widths[0]].copy()
        for _, start, width in self.spans[:-1]:
            reduce(best[:width], images[start: start + width], out=best[:width])
        return best

    def first_attaining(self, images: FloatArray, best: FloatArray) -> RankArray:
        """Per state (this layout's order), the rank among its choices of the first
        whose image equals *best* (0 where none does: a NaN optimum)."""
        if not self.leveled:
            owner = np.repeat(np.arange(best.size), np.diff(self.groups))
            ranks = np.arange(images.size) - self.groups[owner]
            marked = np.where(images == best[owner], ranks, np.iinfo(np.int64).max)
            first = np.minimum.reduceat(marked, self.groups[:-1])
            return np.where(first == np.iinfo(np.int64).max, 0, first)
        # Each level sets its rank where it attains the best, the last (lowest) level
        # winning, as ``rank + hit * (level - rank)`` in int8 (ranks fit: at most DEEPEST
        # levels): no branch per entry, where a masked copy per level took a fifth of
        # a round of resource-gathering's 1,300 (B=1300; 4.5 ms of its 10 ms product).
        states = self.widths[0]
        rank = np.zeros(states, dtype=np.int8)
        hit, step = np.empty(states, dtype=bool), np.empty(states, dtype=np.int8)
        for level, start, width in self.spans:
            np.equal(images[start: start + width], best[:width], out=hit[:width])
            np.subtract(level, rank[:width], out=step[:width])
            step[:width] *= hit[:width].view(np.int8)
            rank[:width] += step[:width]
        return rank

    def chosen(self, rank: RankArray) -> IntArray:
        """The model's choices, per state in the model's order, of *rank* per state in
        this layout's order."""
        return np.asarray(self.restored(rank) + self.groups[:-1], dtype=np.int64)


def _laid_rows(groups: IntArray, order: IntArray, widths: tuple[int, ...]) -> IntArray:
    """Per row of the level layout, the model's choice there."""
    return np.concatenate([groups[order[:width]] + level for level, width in enumerate(widths)])


def _rows_taken(matrix: CsrMatrix, rows: IntArray, order: IntArray) -> CsrMatrix:
    """*matrix*'s *rows*, columns renumbered to positions in *order*, each row's entries
    kept in their stored order (so every product sums in the same order)."""
    lengths = np.diff(matrix.indptr)[rows]
    indptr = np.zeros(rows.size + 1, dtype=np.int64)
    np.cumsum(lengths, out=indptr[1:])
    taken = np.repeat(matrix.indptr[rows] - indptr[:-1], lengths) + np.arange(indptr[-1])
    position = np.empty(order.size, dtype=np.int64)
    position[order] = np.arange(order.size)
    indices = position[matrix.indices[taken]]
    dtype = np.int32 if max(indptr[-1], order.size) < 2**31 else np.int64
    return sp.csr_matrix((matrix.data[taken], indices.astype(dtype), indptr.astype(dtype)),
                         shape=(rows.size, order.size))
