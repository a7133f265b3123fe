"""Commands whose guards fix variables to constants, found by a state's values.

A model written state by state (the DTMC a strategy induces, ``--export-induced``:
one command per state, guarded by ``s=0 & k=0 & ... & rc=0``) has as many commands
as states, and evaluating every guard on every layer of the search is quadratic: the
35,949 commands of a 3 x 3 farm's induced DTMC took 282 s to build. A part of a
choice group whose commands' guards are all conjunctions of ``variable = constant``
(a bool variable also bare or negated) is indexed once instead: each command by the
mixed-radix code of its constants over the variables' ranges, and a layer's states,
coded alike, are matched by a sorted search. A state matches a command exactly where
its guard holds, so the enabledness is the guards' own, bit for bit.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from veribattery._types import BoolArray, IntArray
from veribattery.lang.nodes import Binary, BoolLit, Expr, Ident, IntLit, Unary

__all__ = ["MIN_COMMANDS", "EqualityIndex", "equality_index"]

#: Parts with fewer commands evaluate their guards: the index pays off on many.
MIN_COMMANDS = 32
#: Codes must fit in an int64 with room: the product of the fixed variables' ranges.
_MOST_CODES = 2**62


@dataclass(frozen=True, slots=True)
class _Keyed:
    """The commands that fix one set of variables, by code."""

    columns: IntArray  # the fixed variables' columns in the state vector
    lows: IntArray
    strides: IntArray
    codes: IntArray  # sorted
    commands: IntArray  # the command (position in the part) of each code


@dataclass(frozen=True, slots=True)
class EqualityIndex:
    """Which commands of a part each state enables (see the module doc)."""

    keyed: tuple[_Keyed, ...]
    count: int

    def enabled(self, states: IntArray) -> BoolArray:
        """Enabledness ``(n, commands)``: what the guards evaluate to on *states* (rows
        within the variables' ranges, as every state of a search is)."""
        n = states.shape[0]
        out = np.zeros((n, self.count), dtype=bool)
        for keyed in self.keyed:
            codes = (states[:, keyed.columns] - keyed.lows) @ keyed.strides
            first = np.searchsorted(keyed.codes, codes, side="left")
            hits = np.searchsorted(keyed.codes, codes, side="right") - first
            total = int(hits.sum())
            if not total:
                continue
            rows = np.repeat(np.arange(n), hits)
            starts = np.cumsum(hits) - hits
            at = np.repeat(first - starts, hits) + np.arange(total)
            out[rows, keyed.commands[at]] = True
        return out


def equality_index(guards: Sequence[Expr], names: Sequence[str],
                   ranges: Mapping[str, tuple[int, int]]) -> EqualityIndex | None:
    """The index of a part whose guards are *guards*, or None where it has fewer than
    :data:`MIN_COMMANDS` or a guard is not a conjunction of ``variable = constant``."""
    if len(guards) < MIN_COMMANDS:
        return None
    column = {name: i for i, name in enumerate(names)}
    by_columns: dict[tuple[int, ...], tuple[list[int], list[tuple[int, ...]]]] = {}
    for position, guard in enumerate(guards):
        fixed = _fixed(guard, ranges)
        if fixed is None:
            return None
        if fixed is _NEVER:
            continue  # (contradictory or out of range: enabled nowhere, as its guard)
        columns = tuple(sorted(column[name] for name in fixed))
        commands, values = by_columns.setdefault(columns, ([], []))
        commands.append(position)
        values.append(tuple(fixed[names[c]] for c in columns))
    keyed = [_keyed(columns, commands, values, names, ranges)
             for columns, (commands, values) in by_columns.items()]
    if any(k is None for k in keyed):
        return None
    return EqualityIndex(tuple(k for k in keyed if k is not None), len(guards))


#: A guard that holds nowhere (``x=1 & x=2``, or a constant outside the range).
_NEVER: dict[str, int] = {}


def _fixed(guard: Expr, ranges: Mapping[str, tuple[int, int]]) -> dict[str, int] | None:
    """The values *guard* fixes (``_NEVER`` if it holds nowhere), or None if it is not a
    conjunction of equalities of variables with literals."""
    fixed: dict[str, int] = {}
    never = False
    for term in _conjuncts(guard):
        pair = _equality(term, ranges)
        if pair is None:
            return None
        name, value = pair
        low, high = ranges[name]
        if fixed.get(name, value) != value or not low <= value <= high:
            never = True
        fixed[name] = value
    if not fixed:
        return None  # (``true``: no equality to index by)
    return _NEVER if never else fixed


def _conjuncts(expr: Expr) -> list[Expr]:
    if isinstance(expr, Binary) and expr.op == "&":
        return [*_conjuncts(expr.left), *_conjuncts(expr.right)]
    return [expr]


def _equality(term: Expr, ranges: Mapping[str, tuple[int, int]]) -> tuple[str, int] | None:
    """``(variable, value)`` of ``v = literal``, ``literal = v``, a bool ``v`` or ``!v``."""
    if isinstance(term, Ident) and term.name in ranges:
        return term.name, 1  # (a bare variable in a guard is a bool)
    if isinstance(term, Unary) and term.op == "!" and isinstance(term.operand, Ident) \
            and term.operand.name in ranges:
        return term.operand.name, 0
    if not (isinstance(term, Binary) and term.op == "="):
        return None
    for variable, literal in ((term.left, term.right), (term.right, term.left)):
        value = _literal(literal)
        if isinstance(variable, Ident) and variable.name in ranges and value is not None:
            return variable.name, value
    return None


def _literal(expr: Expr) -> int | None:
    if isinstance(expr, BoolLit):
        return int(expr.value)
    if isinstance(expr, IntLit):
        return expr.value
    if isinstance(expr, Unary) and expr.op == "-" and isinstance(expr.operand, IntLit):
        return -expr.operand.value
    return None


def _keyed(columns: tuple[int, ...], commands: list[int], values: list[tuple[int, ...]],
           names: Sequence[str], ranges: Mapping[str, tuple[int, int]]) -> _Keyed | None:
    lows = np.array([ranges[names[c]][0] for c in columns], dtype=np.int64)
    sizes = [ranges[names[c]][1] - ranges[names[c]][0] + 1 for c in columns]
    if np.prod(np.array(sizes, dtype=object)) >= _MOST_CODES:
        return None
    strides = np.ones(len(columns), dtype=np.int64)
    for i in range(len(columns) - 2, -1, -1):
        strides[i] = strides[i + 1] * sizes[i + 1]
    codes = (np.array(values, dtype=np.int64) - lows) @ strides
    order = np.argsort(codes, kind="stable")  # (ties: the part's order)
    return _Keyed(np.array(columns, dtype=np.int64), lows, strides, codes[order],
                  np.array(commands, dtype=np.int64)[order])
