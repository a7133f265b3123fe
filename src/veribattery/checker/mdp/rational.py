"""Rational arithmetic on a :class:`ChoiceSystem`: exact images and policy iteration.

Shared by the exact engine (:mod:`~veribattery.checker.mdp.exact`) and by the
float engine's last resort for small systems whose certificate stays too wide
(:mod:`~veribattery.checker.mdp.optimum`). A strategy's induced system is
solved SCC by SCC in rationals (:mod:`~veribattery.checker.exact.solve`);
every comparison is exact, so the loop ends exactly when ``B(x) = x``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gmpy2 import mpq

from veribattery._types import IntArray
from veribattery.checker.exact.solve import ExactSystem
from veribattery.checker.exact.solve import solve as solve_linear
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.system import ChoiceSystem, Objective

__all__ = ["ObjectArray", "RationalSystem", "exact_policy_iteration", "exact_probabilities"]

#: One Python object (here :class:`gmpy2.mpq`) per entry.
ObjectArray = np.ndarray

_ZERO = mpq(0)


def exact_probabilities(mdp: MDP) -> ObjectArray:
    """The stored float64 probabilities as the rationals they are (CSR data order)."""
    return np.array([mpq(float(p)) for p in mdp.transitions.data], dtype=object)


@dataclass(frozen=True, slots=True)
class RationalSystem:
    """A :class:`ChoiceSystem` with exact entries, known values and offsets."""

    system: ChoiceSystem
    entries: ObjectArray  # per stored entry of system.off
    entry_row: IntArray
    leave: ObjectArray  # per row, the exact probability of leaving its class
    known: ObjectArray  # per known state of the system
    offset: ObjectArray  # per row

    @classmethod
    def of(cls, system: ChoiceSystem, probabilities: ObjectArray, known: ObjectArray,
           rewards: ObjectArray | None) -> RationalSystem:
        """*system* read exactly: *probabilities* per stored entry of the MDP, *known*
        per known state of the system, *rewards* per choice of the MDP (or None)."""
        entries = probabilities[system.positions]
        entry_row = np.repeat(np.arange(system.off.shape[0]), np.diff(system.off.indptr))
        leave = np.add.reduceat(entries, system.off.indptr[:-1])
        offset = (np.full(system.choices.size, _ZERO, dtype=object) if rewards is None
                  else np.asarray(rewards, dtype=object)[system.choices])
        return cls(system, entries, entry_row, leave, known, offset)

    def images(self, x: ObjectArray) -> ObjectArray:
        """``G_a(x)`` of every row, exactly."""
        full = np.concatenate([x, self.known])
        products = self.entries * full[self.system.off.indices]
        sums = np.add.reduceat(products, self.system.off.indptr[:-1])
        return np.asarray((sums + self.offset) / self.leave, dtype=object)

    def evaluate(self, rows: IntArray) -> ObjectArray:
        """The exact values of the strategy *rows* (one row per class)."""
        size = self.system.size
        chosen = np.zeros(self.system.choices.size, dtype=bool)
        chosen[rows] = True
        local = np.full(self.system.choices.size, -1, dtype=np.int64)
        local[rows] = np.arange(size)
        picked = chosen[self.entry_row]
        columns = self.system.off.indices[picked]
        owner = local[self.entry_row[picked]]
        scaled = self.entries[picked] / self.leave[self.entry_row[picked]]
        inner = columns < size
        rhs = self.offset[rows] / self.leave[rows]
        np.add.at(rhs, owner[~inner], scaled[~inner] * self.known[columns[~inner] - size])
        linear = _merged(size, owner[inner], columns[inner], scaled[inner])
        return np.asarray(solve_linear(linear, rhs), dtype=object)


def _merged(size: int, rows: IntArray, columns: IntArray, values: ObjectArray) -> ExactSystem:
    """The entries with one (row, column) summed: a row of a collapsed class may enter
    another class through several of its states."""
    keys, inverse = np.unique(rows * size + columns, return_inverse=True)
    sums = np.full(keys.size, _ZERO, dtype=object)
    np.add.at(sums, inverse, values)
    return ExactSystem(size, keys // size, keys % size, sums)


def exact_policy_iteration(rational: RationalSystem, objective: Objective,
                      rows: IntArray) -> tuple[IntArray, ObjectArray]:
    """Exact policy iteration from *rows*: the optimal strategy and values."""
    system = rational.system
    starts = system.groups[:-1]
    reduce = np.maximum if objective == "max" else np.minimum
    while True:
        x = rational.evaluate(rows)
        images = rational.images(x)
        best = reduce.reduceat(images, starts)
        now = images[rows]
        better = (best > now) if objective == "max" else (best < now)
        better = np.asarray(better, dtype=bool)
        if not better.any():
            return rows, x
        first = _first_equal(images, best[system.row_class], starts, images.size)
        rows = np.where(better, first, rows)


def _first_equal(values: ObjectArray, best: ObjectArray, starts: IntArray, size: int) -> IntArray:
    """Per group, the first position whose value equals its group's *best*."""
    hits = np.asarray(values == best, dtype=bool)
    positions = np.where(hits, np.arange(size), size)
    return np.asarray(np.minimum.reduceat(positions, starts), dtype=np.int64)
