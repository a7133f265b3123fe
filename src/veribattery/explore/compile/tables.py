"""Lookup tables: a sub-expression over a small domain evaluated once per valuation."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from veribattery._types import IntArray
from veribattery.explore.compile.node import CompileCache, Fn, memoised
from veribattery.explore.compile.shape import cached_shape
from veribattery.lang.nodes import (
    BoolLit,
    DoubleLit,
    Expr,
    Ident,
    IntLit,
    LabelRef,
)

__all__ = [
    "TABLE_LIMIT",
    "narrowed",
    "table_lookup",
    "valuation_grid",
    "worth_tabulating",
]


# ---------------------------------------------------------------------------
# Lookup tables: a deep ``? :`` chain over one small variable (a distance per
# route position, a cost per wind and voltage level) costs dozens of numpy calls
# per BFS layer; tabulated over its variables' domain it costs one gather.
# ---------------------------------------------------------------------------

#: Largest number of valuations a tabulated sub-expression may range over.
TABLE_LIMIT = 1 << 17
#: Largest valuation grid kept for the tables that follow (models with many variables
#: have wide grids; those are rebuilt per table rather than held).
_GRID_KEEP_BYTES = 16 << 20


def worth_tabulating(
    expr: Expr, ranges: Mapping[str, tuple[int, int]], cache: CompileCache | None
) -> bool:
    if isinstance(expr, IntLit | DoubleLit | BoolLit | Ident | LabelRef):
        return False
    names, size = cached_shape(expr, cache)
    if not names or not names <= ranges.keys():
        return False
    valuations = math.prod(ranges[n][1] - ranges[n][0] + 1 for n in names)
    return valuations <= TABLE_LIMIT and size > 2 * len(names) + 1


#: Narrower types a table may be stored in, tried in order, by kind of its values.
_NARROW = {"i": (np.int8, np.int16, np.int32), "f": (np.float32,)}


def narrowed(table: np.ndarray) -> np.ndarray:
    """*table* in the narrowest type that holds each of its values exactly (or as it is).

    A layer's lookups land at random places in a table, and an int64 table over a
    battery's charge and recharges is hundreds of kB: a dozen of them no longer fit
    the L2 cache between two layers, and the misses cost more than the widening
    back after the gather (``table_lookup``).
    """
    for narrow in _NARROW.get(table.dtype.kind, ()):
        with np.errstate(over="ignore", invalid="ignore"):  # 1e45 in float32: refused below
            candidate = table.astype(narrow)
        if np.array_equal(candidate.astype(table.dtype), table):
            return candidate
    return table


def valuation_grid(
    cols: list[int], lows: list[int], shape: list[int], width: int, cache: CompileCache | None
) -> IntArray:
    """Every valuation of the variables *cols* (the other columns 0), shared via *cache*
    by the tables over the same variables.
    """
    key = (tuple(cols), tuple(lows), tuple(shape))
    found = cache.grids.get(key) if cache is not None else None
    if found is None:
        found = np.zeros((math.prod(shape), width), dtype=np.int64)
        found[:, cols] = np.indices(shape).reshape(len(shape), -1).T + np.array(lows)
        if cache is not None and found.nbytes <= _GRID_KEEP_BYTES:
            cache.grids[key] = found
    return found


def table_lookup(
    table: np.ndarray, cols: list[int], lows: list[int], shape: list[int],
    cache: CompileCache | None = None,
) -> Fn:
    narrow = narrowed(table)
    lookup = _lookup_in(narrow, cols, lows, shape, cache)
    if narrow.dtype != table.dtype:  # widened back: later arithmetic must not wrap
        return _widening(table.dtype, lookup)
    return lookup


def _lookup_in(
    table: np.ndarray, cols: list[int], lows: list[int], shape: list[int],
    cache: CompileCache | None,
) -> Fn:
    """The lookup in *table*, stored as it is."""
    strides = [math.prod(shape[i + 1 :]) for i in range(len(shape))]
    offset = sum(low * stride for low, stride in zip(lows, strides, strict=True))
    if len(cols) == 1 and offset == 0:
        (col,) = cols
        return lambda states: table[states[:, col]]
    # Tables over the same variables share their index (computed once per input).
    key = (tuple(cols), tuple(strides), offset)
    index_of = cache.indices.get(key) if cache is not None else None
    if index_of is None:
        index_of = _index(cols, strides, offset)
        if cache is not None:
            index_of = cache.indices[key] = memoised(index_of) if cache.memoise else index_of
    return lambda states: table[index_of(states)]


def _widening(dtype: np.dtype[Any], narrow: Fn) -> Fn:
    """*narrow* (a lookup in a narrowed table) with its values back in *dtype*."""
    return lambda states: narrow(states).astype(dtype)


def _index(cols: list[int], strides: list[int], offset: int) -> Fn:
    """Mixed-radix position of each row's valuation of *cols* in a table."""
    shift = np.asarray(offset, dtype=np.int64)  # a 0-d array: see ``constant_node``
    if len(cols) == 1:
        (col,) = cols
        return lambda states: states[:, col] - shift
    first, stop = min(cols), max(cols) + 1
    weights = np.zeros(stop - first, dtype=np.int64)
    weights[[c - first for c in cols]] = strides

    def evaluate(states: IntArray) -> Any:
        # One product with the strides (zero for the other columns in between)
        # instead of a multiply and an add per column: this runs for every table,
        # every layer. numpy's integer product is a plain loop, so its cost grows
        # with the columns it reads: only those from the first to the last used.
        index = states[:, first:stop] @ weights
        index -= shift
        return index

    return evaluate
