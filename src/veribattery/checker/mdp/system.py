"""The Bellman equations of the unknown states of an MDP, with rigorous images.

After the qualitative pre-pass the unknown states are grouped into *classes*
(one per state, or one per end component that is collapsed, de Alfaro 1997);
each class has the choices of its states that leave it. With ``P'_a`` the
entries of choice *a* that leave its class, ``s_a = sum_j P'_aj`` and ``o_a``
its reward, choice *a* maps a value vector *x* to

    G_a(x) = (o_a + sum_j P'_aj ext(x)_j) / s_a

(``ext(x)`` reads *x* on the classes and the known values elsewhere): the mass
that stays in the class is read as ``1 - s_a``, exactly -- the reading the DTMC
side gives a self-loop (``docs/numerics.md``), of which a collapsed class is the
generalisation. The Bellman operator is the maximum or minimum of ``G_a`` over
each class's choices. Dividing by ``s_a`` changes no fixed point and no test
``B(u) <= u``: for ``s_a > 0``, ``G_a(u) <= u_c`` iff ``o_a + P'_a ext(u) +
(1 - s_a) u_c <= u_c`` (``docs/mdp-numerics.md``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, TypeVar

import numpy as np
import scipy.sparse as sp

from veribattery._types import BoolArray, CsrMatrix, FloatArray, IntArray
from veribattery._unique import distinct_inverse
from veribattery.checker.certify import (
    UNIT_ROUNDOFF,
    enclose_product,
    nonzero_terms,
    product_error,
    step_down_in_place,
    step_up_in_place,
)
from veribattery.checker.mdp.graph import ChoiceGraph, segments

__all__ = ["ChoiceSystem", "ClassRows", "LiveRows", "Objective", "enclosed_quotients", "equations",
           "quotient_classes"]

#: Which player the values are optimal for.
Objective = Literal["min", "max"]
#: Per row, a value (an image, a row index) to take the best of per class.
RowValues = TypeVar("RowValues", FloatArray, IntArray)
#: Classes of at most this many rows take the best of their rows a row at a time
#: (:class:`ClassRows`); larger ones by ``reduceat``.
FEW_ROWS = 8


@dataclass(frozen=True, slots=True)
class ClassRows:
    """Where each class's rows lie, to take the best of rigorous row images quickly.

    ``reduceat`` pays some 15 ns per class, more than the comparisons themselves on a
    system of many classes of one to three rows (a third of a full image of the
    mission MDP); here each class's first row is read, then its second, third, ... in
    whole-array operations, the same comparisons in the same order as ``reduceat``'s.
    (Rigorous images hold no NaN and no -0.0 -- the bounds replace NaN and clip at +0.0
    -- so their maximum or minimum is the same float in any order anyway.)

    :param firsts: per class, its first row.
    :param later: per row position ``k = 1, 2, ...``: the classes of at most
        :data:`FEW_ROWS` rows that have a row there, and that row.
    :param large: the classes of more rows; *large_rows* their rows, class by class,
        and *large_starts* where each class begins in them.
    """

    firsts: IntArray
    later: tuple[tuple[IntArray, IntArray], ...]
    large: IntArray
    large_rows: IntArray
    large_starts: IntArray

    @classmethod
    def of(cls, groups: IntArray) -> ClassRows:
        """The layout of the classes whose rows start at *groups* (then the end)."""
        firsts, sizes = groups[:-1], np.diff(groups)
        few = sizes <= FEW_ROWS
        later = []
        for k in range(1, int(np.max(np.where(few, sizes, 0), initial=0))):
            classes = np.flatnonzero(few & (sizes > k))
            later.append((classes, firsts[classes] + k))
        large = np.flatnonzero(~few)
        lengths = sizes[large]
        return cls(firsts, tuple(later), large, segments(groups, large),
                   np.cumsum(lengths) - lengths)

    def best(self, row_values: RowValues, objective: Objective) -> RowValues:
        """Per class, the maximum or minimum of its *row_values* (each class taking its
        rows in order, as ``reduceat`` does)."""
        reduce = np.maximum if objective == "max" else np.minimum
        best = row_values[self.firsts]
        for classes, rows in self.later:
            best[classes] = reduce(best[classes], row_values[rows])
        if self.large.size:
            best[self.large] = reduce.reduceat(row_values[self.large_rows], self.large_starts)
        return best


@dataclass(frozen=True, slots=True)
class ChoiceSystem:
    """The equations of *size* classes: one row per choice that leaves its class.

    :param class_of: per state, its class, or -1 for a state whose value is known.
    :param choices: per row, the MDP's choice index (rows grouped by class).
    :param groups: ``size + 1`` offsets of each class's rows.
    :param off: rows x ``(size + len(known_states))``: the entries that leave the row's
        class, columns ``0..size-1`` the classes, then the known states.
    :param positions: per stored entry of *off*, its position in the MDP's
        ``transitions.data`` (for exact arithmetic on the same rows).
    :param known_states: the states of known value that some row reaches.
    :param leave: per row, ``s_a`` in floating point.
    :param leave_lower: a rigorous lower bound of ``s_a`` (its exact sum).
    :param leave_upper: a rigorous upper bound of ``s_a``.
    :param layout: the rows of each class (``ClassRows.of(groups)``).
    """

    class_of: IntArray
    choices: IntArray
    groups: IntArray
    off: CsrMatrix
    positions: IntArray
    known_states: IntArray
    leave: FloatArray
    leave_lower: FloatArray
    leave_upper: FloatArray
    #: Where each class's rows lie (:meth:`best` reads it).
    layout: ClassRows

    @property
    def size(self) -> int:
        """Number of classes (unknowns)."""
        return int(self.groups.size - 1)

    @property
    def row_class(self) -> IntArray:
        """The class of each row."""
        return np.repeat(np.arange(self.size, dtype=np.int64), np.diff(self.groups))

    def graph(self) -> ChoiceGraph:
        """The rows as a choice graph over classes then known states."""
        return ChoiceGraph.of(self.off, self.row_class)

    def images(self, x: FloatArray, known: FloatArray, offset: FloatArray | None) -> FloatArray:
        """``G_a(x)`` of every row in floating point (not rigorous)."""
        numerator = self.off @ np.concatenate([x, known])
        if offset is not None:
            numerator = numerator + offset
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return np.asarray(numerator / self.leave, dtype=np.float64)

    def bound_images(self, x: FloatArray, known: FloatArray, offset: FloatArray | None,
                     *, up: bool, rows: IntArray | None = None) -> FloatArray:
        """Rigorous bounds of ``G_a(x)`` per row: from above if *up*, else from below.

        *x*, *known* and *offset* must be nonnegative (so is every term). The
        numerator's rounding is bounded by Higham's ``gamma_k`` over the row's *nonzero*
        terms only (a product with an exact 0 is exactly 0 and adding it is exact), so
        a row that reads only zeros has the exact image 0 -- which lets exact zeros
        pass the certificate's tests. The quotient is divided by the other side of
        ``s_a``'s enclosure and stepped one float outward (and clamped at 0 below).

        :param rows: only these rows, in this order (None: all); each row's bound is
            the same float either way.
        """
        return self.extended_bound_images(np.concatenate([x, known]), offset, up=up,
                                          rows=rows)

    def extended_bound_images(self, extended: FloatArray, offset: FloatArray | None,
                              *, up: bool, rows: IntArray | None = None,
                              live: LiveRows | None = None) -> FloatArray:
        """:meth:`bound_images` of ``ext(x)``: *x* followed by the known values.

        :param live: with every row, :meth:`live_rows` of *extended* and *offset*, if known.
        """
        if rows is None:
            if live is None:
                live = self.live_rows(extended != 0, offset, up=up)
            return _bounded_images(self.off, live, extended, offset)
        off = self.off[rows]
        offset = None if offset is None else offset[rows]
        return _bounded_images(off, LiveRows.of(nonzero_terms(off, extended), offset,
                                                self.leave_lower[rows],
                                                self.leave_upper[rows], up=up),
                               extended, offset)

    def live_rows(self, nonzero: BoolArray, offset: FloatArray | None, *,
                  up: bool) -> LiveRows:
        """The rows with a nonzero term when the entries *nonzero* of ``ext(x)`` are."""
        return LiveRows.of(nonzero_terms(self.off, nonzero), offset, self.leave_lower,
                           self.leave_upper, up=up)

    def defect(self, x: FloatArray, known: FloatArray, offset: FloatArray | None,
               objective: Objective) -> FloatArray:
        """An upper bound of ``|B(x) - x|`` per class from the rigorous images (plus four
        units of roundoff of *x*, the certificate's floor): the defect its margin is
        made of (*x* is clipped at 0)."""
        x = np.maximum(x, 0.0)
        with np.errstate(invalid="ignore", over="ignore"):
            above = self.best(self.bound_images(x, known, offset, up=True), objective) - x
            below = x - self.best(self.bound_images(x, known, offset, up=False), objective)
        return np.maximum(np.maximum(above, below), 0.0) + 4.0 * UNIT_ROUNDOFF * x

    def restricted(self, keep: BoolArray) -> ChoiceSystem:
        """The same classes with only the rows *keep* (each class must keep one)."""
        counts = np.bincount(self.row_class[keep], minlength=self.size)
        if np.any(counts == 0):
            raise ValueError("every class needs a row")
        entries = np.repeat(keep, np.diff(self.off.indptr))
        off = sp.csr_matrix(self.off[np.flatnonzero(keep)])
        groups = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        return ChoiceSystem(self.class_of, self.choices[keep], groups, off,
                            self.positions[entries], self.known_states, self.leave[keep],
                            self.leave_lower[keep], self.leave_upper[keep],
                            ClassRows.of(groups))

    def best(self, row_values: FloatArray, objective: Objective) -> FloatArray:
        """The maximum or minimum of *row_values* over each class's rows."""
        return np.asarray(self.layout.best(row_values, objective), dtype=np.float64)

    def best_of(self, row_values: FloatArray, classes: IntArray,
                objective: Objective) -> FloatArray:
        """:meth:`best` of the (sorted, distinct) *classes* only."""
        reduce = np.maximum if objective == "max" else np.minimum
        positions = segments(self.groups, classes)
        starts = np.cumsum(self.groups[classes + 1] - self.groups[classes]) - (
            self.groups[classes + 1] - self.groups[classes])
        return np.asarray(reduce.reduceat(row_values[positions], starts), dtype=np.float64)

    def best_rows(self, row_values: FloatArray, objective: Objective) -> IntArray:
        """Per class, the first row attaining :meth:`best`."""
        best = self.best(row_values, objective)
        hits = row_values == best[self.row_class]
        rows = np.where(hits, np.arange(row_values.size), row_values.size)
        return np.asarray(self.layout.best(rows, "min"), dtype=np.int64)


@dataclass(frozen=True, slots=True)
class LiveRows:
    """The rows of a rigorous image that read a nonzero term, and what their bounds
    read: the same while the same entries of the argument are 0.

    A row without a nonzero term has the exact image 0 (every formula of
    :func:`_bounded_images` gives 0 there, through subnormal steps that cost ~10x):
    only the others are computed.

    :param rows: the live rows (None: every row).
    :param count: the number of rows in all.
    :param terms: per live row, its nonzero terms (the offset's included).
    :param leave: per live row, the side of ``s_a``'s enclosure the bound divides by.
    :param up: whether the bounds are upper bounds.
    """

    rows: IntArray | None
    count: int
    terms: FloatArray
    leave: FloatArray
    up: bool

    @classmethod
    def of(cls, terms: FloatArray, offset: FloatArray | None, leave_lower: FloatArray,
           leave_upper: FloatArray, *, up: bool) -> LiveRows:
        """The live rows of the per-row nonzero *terms* (and *offset*)."""
        if offset is not None:
            terms = terms + (offset != 0)
        leave = leave_lower if up else leave_upper
        live = np.flatnonzero(terms)
        if live.size == terms.size:
            return cls(None, terms.size, terms, leave, up)
        return cls(live, terms.size, terms[live], leave[live], up)


def _bounded_images(off: CsrMatrix, live: LiveRows, full: FloatArray,
                    offset: FloatArray | None) -> FloatArray:
    """:meth:`ChoiceSystem.bound_images` of the rows *off* (*full* the classes' then the
    known states' values), on the side of *live*."""
    numerator = np.asarray(off @ full, dtype=np.float64)
    if offset is not None:
        numerator = numerator + offset
    if live.rows is not None:
        numerator = numerator[live.rows]
    quotient = enclosed_quotients(numerator, live.terms, live.leave, up=live.up)
    if live.rows is None:
        return quotient
    images = np.zeros(live.count, dtype=np.float64)
    images[live.rows] = quotient
    return images


def enclosed_quotients(numerator: FloatArray, terms: FloatArray, leave: FloatArray, *,
                       up: bool) -> FloatArray:
    """Rigorous bounds of the rows' ``G_a`` from their float *numerator* (``P'_a ext(x)``
    plus the reward, >= 0; overwritten), their nonzero *terms* (the reward's included)
    and the side of ``s_a``'s enclosure to divide by (*leave*: its lower bound if *up*,
    else its upper bound)."""
    error = product_error(numerator, terms, terms)
    # The formulas of :meth:`ChoiceSystem.bound_images`, in place on the vectors made
    # here: the same operations on the same floats, without a temporary per step.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return (_upper_quotient(numerator, error, leave) if up
                else _lower_quotient(numerator, error, leave))


def _upper_quotient(numerator: FloatArray, error: FloatArray,
                    leave_lower: FloatArray) -> FloatArray:
    """``step_up(step_up(numerator + error) / leave_lower)``, 0 where the sum is 0 and
    ``inf`` where NaN (in *error*'s storage; every entry is >= 0, NaN or ``+inf``)."""
    error += numerator
    zero = error == 0
    step_up_in_place(error)
    error /= leave_lower
    step_up_in_place(error)
    error[zero] = 0.0
    error[np.isnan(error)] = np.inf
    return error


def _lower_quotient(numerator: FloatArray, error: FloatArray,
                    leave_upper: FloatArray) -> FloatArray:
    """``max(step_down(max(step_down(numerator - error), 0) / leave_upper), 0)``, 0 where
    NaN (in *numerator*'s storage)."""
    numerator -= error
    # A difference <= 0 steps down below 0 and is clipped to 0: clipping it first
    # gives the same 0 and leaves only entries >= 0 (or NaN) to step down.
    np.maximum(numerator, 0.0, out=numerator)
    step_down_in_place(numerator)
    np.maximum(numerator, 0.0, out=numerator)
    numerator /= leave_upper
    step_down_in_place(numerator)
    numerator[np.isnan(numerator)] = 0.0
    np.maximum(numerator, 0.0, out=numerator)
    return numerator


def equations(transitions: CsrMatrix, owner: IntArray, class_of: IntArray,
              allowed: BoolArray | None = None) -> ChoiceSystem:
    """The rows of the classes of *class_of* (states with -1 are known).

    :param transitions: the MDP's choice matrix; *owner* the state of each choice.
    :param allowed: the choices that may be used (None: all); choices that keep all
        their mass in their class are dropped (they never change a value).
    :raises ValueError: when a class is left without any row.
    """
    size = int(class_of.max(initial=-1)) + 1
    candidate = class_of[owner] >= 0
    if allowed is not None:
        candidate &= allowed
    rows = np.flatnonzero(candidate)
    rows = rows[np.argsort(class_of[owner[rows]], kind="stable")]
    positions, leaving = _leaving_entries(transitions, owner, class_of, rows)
    # Every entry found belongs to a row that leaves: dropping the others keeps the rest.
    rows, leaving = rows[leaving > 0], leaving[leaving > 0]
    counts = np.bincount(class_of[owner[rows]], minlength=size)
    if np.any(counts == 0):
        raise ValueError(f"{int(np.sum(counts == 0))} classes have no choice leaving them")
    if transitions.nnz < 2**31:  # (kept while the system lives: an int32 where it fits)
        positions = positions.astype(np.int32)
    off, known_states = _matrix(transitions, class_of, positions, leaving, size)
    leave, leave_lower, leave_upper = enclose_product(off, np.ones(off.shape[1]))
    groups = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return ChoiceSystem(class_of, rows, groups, off, positions, known_states, leave,
                        np.maximum(leave_lower, 0.0), leave_upper, ClassRows.of(groups))


def _leaving_entries(transitions: CsrMatrix, owner: IntArray, class_of: IntArray,
                     rows: IntArray) -> tuple[IntArray, IntArray]:
    """Positions of the positive entries of *rows* outside the row's class (row by row,
    in their stored order), and how many each row has."""
    starts = transitions.indptr[rows].astype(np.int64)
    lengths = transitions.indptr[rows + 1].astype(np.int64) - starts
    row_of = np.repeat(np.arange(rows.size, dtype=np.int64), lengths)
    ends = np.cumsum(lengths)
    positions = np.repeat(starts, lengths) + (np.arange(row_of.size) - np.repeat(ends - lengths,
                                                                                 lengths))
    column_class = class_of[transitions.indices[positions]]
    keep = (transitions.data[positions] > 0) & (column_class != class_of[owner[rows]][row_of])
    return positions[keep], np.bincount(row_of[keep], minlength=rows.size)


def _matrix(transitions: CsrMatrix, class_of: IntArray, positions: IntArray,
            lengths: IntArray, size: int) -> tuple[sp.csr_matrix, IntArray]:
    """The entries at *positions*, *lengths* a row, in the classes' columns (see
    :func:`_local_columns`), and the known states of the columns past *size*. (Its own
    function so that the int64 columns die here, before the caller's enclosure.)"""
    columns, known_states = _local_columns(class_of, transitions.indices[positions], size)
    indptr = np.zeros(lengths.size + 1, dtype=np.int64)
    np.cumsum(lengths, out=indptr[1:])
    off = sp.csr_matrix((transitions.data[positions], columns, indptr),
                        shape=(lengths.size, size + known_states.size))
    return off, known_states


def _local_columns(class_of: IntArray, columns: IntArray, size: int) -> tuple[IntArray, IntArray]:
    """Columns renumbered: a class keeps its index, a known state gets ``size + k``."""
    column_class = class_of[columns]
    known = column_class < 0
    known_states, inverse = distinct_inverse(columns[known])
    local = column_class.copy()
    local[known] = size + inverse
    return local, known_states.astype(np.int64)


def quotient_classes(unknown: BoolArray, component: IntArray | None = None) -> IntArray:
    """Classes of the *unknown* states: one per end component in *component* (>= 0),
    one per other unknown state; -1 for the states that are not unknown."""
    class_of = np.full(unknown.size, -1, dtype=np.int64)
    if component is None:
        class_of[unknown] = np.arange(int(unknown.sum()))
        return class_of
    grouped = unknown & (component >= 0)
    _, dense = np.unique(component[grouped], return_inverse=True)
    class_of[grouped] = dense
    count = int(dense.max(initial=-1)) + 1
    single = unknown & ~grouped
    class_of[single] = count + np.arange(int(single.sum()))
    return class_of
