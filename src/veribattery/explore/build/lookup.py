"""Many small expressions evaluated on a frontier by one gather from their tables.

A deep, narrow search (brp of N=2048: 12,313 BFS layers of ~24 states) spends its
time in numpy's fixed cost per call, and a guard costs a few calls per layer
however few states it sees. Every expression whose variables span at most
``UNIT_LIMIT`` valuations, and that has a value at each of them, is tabulated
once over them; the tables are laid end to end, and one product of the frontier
with their strides gives each state's position in every table. A layer then
evaluates all of them with four numpy calls.

A table holds what the compiled expression gives on its valuation grid, element
by element the same operations as on the states themselves, so a lookup gives
the same value. An expression that fails on some valuation (``mod(x, y)`` at
``y=0``, even where a guard would never evaluate it) is not tabulated.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.errors import ModelError
from veribattery.explore.compile.expr import (
    CompileCache,
    CompiledExpr,
    compile_expr,
    variables_of,
)
from veribattery.explore.compile.tables import valuation_grid
from veribattery.lang.nodes import Binary, BoolLit, Expr

__all__ = ["DEEP", "NARROW", "UNIT_LIMIT", "Lookup", "LookupBuilder", "NarrowLookups",
           "NarrowPath", "TabulatedGuards", "conjuncts", "tabulate_guards"]

#: Largest number of valuations a unit's table may have.
UNIT_LIMIT = 1 << 16
#: Largest number of entries of all the tables of one lookup (they should stay in cache).
_TOTAL_LIMIT = 1 << 21
#: Positions are computed in float64 (a BLAS product): exact while below this.
_EXACT = float(1 << 52)


@dataclass(frozen=True, slots=True)
class Lookup:
    """Tables laid end to end, and each one's strides over the state's variables.

    :param strides: ``(units, n_vars)``: a state's position in unit *u*'s table,
        minus ``bases[u]``, is ``strides[u] @ state``.
    :param bases: ``(units, 1)``: each table's start, less its variables' lows times
        their strides.
    :param table: the values, every unit's table in order.
    """

    strides: FloatArray
    bases: FloatArray
    table: np.ndarray

    @property
    def units(self) -> int:
        """The number of tabulated expressions."""
        return int(self.bases.shape[0])

    def evaluate(self, states: IntArray) -> np.ndarray:
        """``(units, n)``: every unit's value in every state of *states* ``(n, n_vars)``."""
        position = self.strides @ states.T  # float64: one BLAS product for every unit
        position += self.bases
        index: IntArray = position.astype(np.intp)
        values: np.ndarray = self.table.take(index)
        return values


class LookupBuilder:
    """Collects the units of one :class:`Lookup`: each distinct expression once.

    :param names: the state's variables, in column order.
    :param ranges: each variable's (low, high).
    :param dtype: the values' type: bool (guards) or int64 (assignments).
    """

    def __init__(self, names: Sequence[str], ranges: Mapping[str, tuple[int, int]],
                 dtype: type[np.generic]) -> None:
        self._names = tuple(names)
        self._ranges = ranges
        self._dtype = dtype
        # Per set of variables compiled over (no memo: no state array kept alive).
        self._caches: dict[tuple[str, ...], CompileCache] = {}
        self._keys = CompileCache(memoise=False)  # structural numbers: no recursive hash
        self._units: dict[int, int] = {}
        self._tables: list[np.ndarray] = []
        self._strides: list[dict[int, int]] = []
        self._offsets: list[int] = []  # sum of low * stride over each unit's variables
        self._size = 0

    def add(self, expr: Expr) -> int | None:
        """The unit of *expr*, tabulated now if new; None if it cannot be tabulated
        (too many valuations, a failure on one, or values of another type)."""
        key = self._keys.key(expr)
        found = self._units.get(key)
        if found is not None:
            return found
        made = self._tabulated(expr)
        if made is None:
            return None
        table, strides, offset = made
        self._units[key] = unit = len(self._tables)
        self._tables.append(table)
        self._strides.append(strides)
        self._offsets.append(offset)
        self._size += table.size
        return unit

    @property
    def units(self) -> int:
        """The number of units added so far."""
        return len(self._tables)

    def finish(self, order: Sequence[int] | None = None) -> Lookup:
        """The lookup of the units in *order* (a unit may repeat; default: each unit
        added, in order)."""
        bases, start = [], 0
        for table, offset in zip(self._tables, self._offsets, strict=True):
            bases.append(start - offset)
            start += table.size
        order = range(len(self._tables)) if order is None else order
        strides = np.zeros((len(order), len(self._names)), dtype=np.float64)
        for row, unit in enumerate(order):
            for column, stride in self._strides[unit].items():
                strides[row, column] = stride
        table = (np.concatenate(self._tables) if self._tables
                 else np.empty(0, dtype=self._dtype))
        return Lookup(strides, np.array([[bases[u]] for u in order], dtype=np.float64), table)

    def _tabulated(self, expr: Expr) -> tuple[np.ndarray, dict[int, int], int] | None:
        """*expr*'s table, its variables' strides by column and its offset, or None."""
        names = sorted(variables_of(expr, self._keys), key=self._names.index)
        if any(n not in self._ranges for n in names):
            return None
        lows = [self._ranges[n][0] for n in names]
        shape = [self._ranges[n][1] - low + 1 for n, low in zip(names, lows, strict=True)]
        size = math.prod(shape)
        if size > UNIT_LIMIT or self._size + size > _TOTAL_LIMIT:
            return None
        strides = [math.prod(shape[i + 1:]) for i in range(len(shape))]
        reach = sum(max(abs(low), abs(low + extent - 1)) * stride
                    for low, extent, stride in zip(lows, shape, strides, strict=True))
        if reach + self._size + size >= _EXACT:
            return None
        table = self._values(expr, names, (lows, shape))
        if table is None:
            return None
        columns = [self._names.index(n) for n in names]
        offset = sum(low * stride for low, stride in zip(lows, strides, strict=True))
        return table, dict(zip(columns, strides, strict=True)), offset

    def _values(self, expr: Expr, names: list[str],
                grid: tuple[list[int], list[int]]) -> np.ndarray | None:
        """*expr* on every valuation of *names* (first most significant), or None.

        Compiled over its own variables only: the grid has a column per variable of
        *expr*, not per variable of the model.
        """
        cache = self._caches.setdefault(tuple(names), CompileCache(memoise=False))
        ranges = {n: self._ranges[n] for n in names}
        fn = compile_expr(expr, names, ranges=ranges, cache=cache)
        lows, shape = grid
        states = (valuation_grid(list(range(len(names))), lows, shape, len(names), cache)
                  if names else np.zeros((1, 0), dtype=np.int64))
        try:
            with np.errstate(all="ignore"):  # x/0 is infinite: a value as any other
                values = np.asarray(fn(states))
        except ModelError:
            return None
        return _typed(np.broadcast_to(values, states.shape[:1]), self._dtype)


def _typed(values: np.ndarray, dtype: type[np.generic]) -> np.ndarray | None:
    """*values* as *dtype*, as the expansion stores them; None if they are not of its
    kind (a double assigned to an integer variable is an error the expansion reports)."""
    kind: Any = values.dtype.kind
    if dtype is np.bool_:
        return values.astype(bool)
    if kind not in "biu":
        return None
    return values.astype(dtype)


def conjuncts(expr: Expr) -> list[Expr]:
    """The operands of *expr*'s top-level chain of ``&`` (itself if it is none)."""
    found: list[Expr] = []
    pending = [expr]
    while pending:
        node = pending.pop()
        if isinstance(node, Binary) and node.op == "&":
            pending.extend((node.right, node.left))
        else:
            found.append(node)
    return found


#: The largest frontier whose guards are looked up all at once: the product costs
#: about 0.2 us per state and unit, a guard's own lookup a few calls per layer.
NARROW = 128
#: Narrow layers expanded before the lookups are made (tens of ms for a mission's
#: large guards): a search still narrow after as many is deep (brp: thousands of
#: layers), a mission's has 136 of its 709 layers.
DEEP = 256


@dataclass(frozen=True, slots=True)
class NarrowLookups:
    """What a narrow layer looks up: the guards, and the right-hand sides.

    :param lookup: the tables of the guards' units, then of the right-hand sides.
    :param guards: the tabulated guards (their units: the lookup's first rows), or None.
    :param value_rows: each looked-up right-hand side's row in the layer's table of
        values (see ``fused.ValueTable``), in the lookup's order, from row *first_value*.
    :param looked_up: their indices among the plan's value expressions.
    """

    lookup: Lookup
    guards: TabulatedGuards | None
    value_rows: IntArray
    looked_up: frozenset[int]
    first_value: int


class NarrowPath:
    """A plan's lookups, made once its search has proven deep and narrow.

    :param make: makes the lookups (once).
    """

    def __init__(self, make: Callable[[], NarrowLookups]) -> None:
        self._make = make
        self._made: NarrowLookups | None = None
        self._narrow = 0

    def lookups(self, n: int) -> NarrowLookups | None:
        """The lookups for a frontier of *n* states: None if it is wide, or until
        ``DEEP`` narrow frontiers have been expanded without them."""
        if n > NARROW:
            return None
        if self._made is None:
            self._narrow += 1
            if self._narrow <= DEEP:
                return None
            self._made = self._make()
        return self._made


@dataclass(frozen=True, slots=True)
class TabulatedGuards:
    """The guards of a program's commands, looked up at once on a narrow frontier.

    Its methods take a lookup's values ``(units, n)`` on the frontier (0 is false).

    :param units: ``(commands + 1, m)``: the units whose conjunction is each command's
        guard (padded with a true unit, only that for a guard left to be evaluated).
    :param residual: per part position, the guards that were not tabulated, as
        ``LayerPlan.guards`` lists them.
    :param kinds: when every guard is tabulated, ``(kinds + 1, m)``: the units whose
        conjunction is each choice kind's enabledness (the last row: any).
    """

    units: IntArray
    residual: tuple[tuple[tuple[int, CompiledExpr, tuple[int, ...]], ...], ...]
    kinds: IntArray | None = None

    def guards(self, looked: IntArray) -> BoolArray:
        """``(commands + 1, n)``: each tabulated guard in each state, true elsewhere."""
        return _conjunction(looked[self.units])

    def enabled(self, looked: IntArray) -> BoolArray:
        """``(kinds + 1, n)``: whether each choice kind is enabled in each state (the
        last row unset); only when every guard is tabulated (*kinds* is set)."""
        assert self.kinds is not None
        return _conjunction(looked[self.kinds])


def _conjunction(values: IntArray) -> BoolArray:
    """``(rows, n)``: the conjunction of *values* ``(rows, m, n)`` over its middle axis,
    as a new bool array."""
    if values.shape[1] == 1:
        found: BoolArray = values[:, 0] != 0
        return found
    conjunction: BoolArray = np.logical_and.reduce(values, axis=1)
    return conjunction


def tabulate_guards(
    guards: tuple[tuple[tuple[int, CompiledExpr, tuple[int, ...]], ...], ...],
    exprs: Mapping[int, Expr],
    builder: LookupBuilder,
    kind_commands: IntArray,
) -> TabulatedGuards | None:
    """*guards* (per part position, as ``LayerPlan.guards``) tabulated where they can be,
    as units of *builder* (int64: 0 is false); None if none can.

    :param exprs: each command's guard expression.
    :param kind_commands: ``(kinds + 1, parts)``: each choice kind's command per
        part (as ``LayerPlan.kind_commands``; the number of commands for none).
    """
    commands = int(kind_commands.max(initial=0))
    true = builder.add(BoolLit(True))
    found: dict[int, list[int]] = {}
    for part in guards:
        for c, _, _ in part:
            made = _guard_units(exprs[c], builder)
            if made is not None:
                found[c] = made
    if true is None or not found:
        return None
    width = max(len(u) for u in found.values())
    table = np.full((commands + 1, width), true, dtype=np.int64)
    for c, units in found.items():
        table[c, : len(units)] = units
    residual = tuple(tuple(g for g in part if g[0] not in found) for part in guards)
    kinds = None if any(residual) else _kind_units(kind_commands, found, true)
    return TabulatedGuards(table, residual, kinds)


def _kind_units(kind_commands: IntArray, found: Mapping[int, list[int]], true: int) -> IntArray:
    """Per choice kind, the units of all its commands' guards (padded with *true*)."""
    rows = [[u for c in row for u in found.get(c, ())] for row in kind_commands.tolist()]
    table = np.full((len(rows), max(1, *map(len, rows))), true, dtype=np.int64)
    for k, units in enumerate(rows):
        table[k, : len(units)] = units
    return table


def _guard_units(guard: Expr, builder: LookupBuilder) -> list[int] | None:
    """The units of *guard*: itself, else its conjuncts, else None."""
    whole = builder.add(guard)
    if whole is not None:
        return [whole]
    parts = conjuncts(guard)
    if len(parts) == 1:
        return None
    units = [builder.add(part) for part in parts]
    if any(u is None for u in units):
        return None
    return [u for u in units if u is not None]
