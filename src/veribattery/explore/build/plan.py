"""The static tables of a fused layer expansion, made once per program.

:func:`plan_layers` enumerates the program's choice kinds (per group: one per
command, or one per combination of one command per synchronising module) and their
branch kinds (one per combination of updates), and tabulates, per branch kind, its
probability factors and which expression each variable takes: the
:class:`~veribattery.explore.build.fused.LayerPlan` that :mod:`.fused` expands a BFS
layer with.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from veribattery._types import IntArray
from veribattery.explore.build.fused import (
    SUM_TOLERANCE,
    AssignedEntries,
    FactorTable,
    LayerExpr,
    LayerPlan,
    ValueTable,
)
from veribattery.explore.build.lookup import (
    LookupBuilder,
    NarrowLookups,
    NarrowPath,
    tabulate_guards,
)
from veribattery.explore.compile.expr import CompiledExpr, may_fail
from veribattery.explore.compile.program import CompiledCommand, Program
from veribattery.lang.nodes import Expr, Ident

__all__ = ["MAX_BRANCH_KINDS", "MAX_KINDS", "plan_layers"]

#: Plans with more choice or branch kinds than this are not built (the enabledness
#: matrix has one column per choice kind): such programs expand group by group.
MAX_KINDS = 512
MAX_BRANCH_KINDS = 4096


# ---------------------------------------------------------------------------
# Building the plan
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Kind:
    action: str | None
    commands: tuple[int, ...]  # global command indices, one per part


def plan_layers(program: Program) -> LayerPlan | None:
    """The fused plan of *program*, or None if it has too many choice or branch kinds."""
    commands, kinds = _enumerate_kinds(program)
    if kinds is None:
        return None
    widths = [math.prod(len(commands[c].updates) for c in k.commands) for k in kinds] + [1]
    if len(kinds) > MAX_KINDS or sum(widths) > MAX_BRANCH_KINDS:
        return None
    branches = _branch_updates(commands, kinds)
    guards = _part_guards(commands, kinds)
    kind_commands = _kind_commands(kinds, len(commands))
    values, sources = _values(program, commands, kinds, branches)
    # A program with rational guards or assignments: tables of its expressions'
    # doubles would not be its functions' values.
    narrow = None if program.exact else NarrowPath(functools.partial(
        _narrow_lookups, program, (commands, guards, kind_commands), values, sources))
    return LayerPlan(
        guards=guards,
        commands=len(commands),
        kind_commands=kind_commands,
        widths=np.array(widths, dtype=np.int64),
        starts=np.cumsum([0, *widths[:-1]]).astype(np.int64),
        values=values,
        factors=_factors(commands, kinds, branches),
        unchecked_sums=_unchecked_sums(commands, kinds),
        action_kinds=_action_kinds(kinds),
        lows=np.array(program.lows, dtype=np.int64),
        highs=np.array(program.highs, dtype=np.int64),
        spans=_spans(program.lows, program.highs),
        narrow=narrow,
    )


def _narrow_lookups(
    program: Program,
    structure: tuple[Sequence[CompiledCommand],
                     tuple[tuple[tuple[int, CompiledExpr, tuple[int, ...]], ...], ...], IntArray],
    values: ValueTable,
    sources: Sequence[Expr | None],
) -> NarrowLookups:
    """The lookups of a narrow layer: the guards (of the commands, per part and per kind:
    *structure*) and the right-hand sides of *values* (their *sources*)."""
    commands, guards, kind_commands = structure
    # One lookup for both (int64, guards 0 or 1): the guards' units, then the values'.
    builder = LookupBuilder(program.variable_names, _ranges(program), np.int64)
    exprs = {c: commands[c].command.guard for part in guards for c, _, _ in part}
    tabulated = tabulate_guards(guards, exprs, builder, kind_commands)
    first = builder.units
    value_units, looked_up = _value_units(builder, sources, values.exprs)
    base = len(program.variable_names) + values.constants.size
    return NarrowLookups(builder.finish([*range(first), *value_units]), tabulated,
                         looked_up + base, frozenset(looked_up.tolist()), first)


def _spans(lows: Sequence[int], highs: Sequence[int]) -> np.ndarray | None:
    spans = [high - low for low, high in zip(lows, highs, strict=True)]
    return np.array(spans, dtype=np.uint64) if max(spans, default=0) < 1 << 63 else None


def _enumerate_kinds(program: Program) -> tuple[list[CompiledCommand], list[_Kind] | None]:
    """All commands, and the choice kinds in the builder's order (None if too many)."""
    commands: list[CompiledCommand] = []
    kinds: list[_Kind] = []
    for group in program.groups:
        parts = []
        for part in group.parts:
            parts.append(tuple(range(len(commands), len(commands) + len(part))))
            commands.extend(part)
        if len(parts) == 1:
            kinds.extend(_Kind(group.action, (c,)) for c in parts[0])
            continue
        if math.prod(len(p) for p in parts) > MAX_KINDS:
            return commands, None
        kinds.extend(_Kind(group.action, combo) for combo in itertools.product(*parts))
    return commands, kinds


def _part_guards(
    commands: Sequence[CompiledCommand], kinds: Sequence[_Kind]
) -> tuple[tuple[tuple[int, CompiledExpr, tuple[int, ...]], ...], ...]:
    """Per part position, each non-trivial guard there with the kinds that use it."""
    users: dict[tuple[int, int], list[int]] = {}
    for k, kind in enumerate(kinds):
        for p, c in enumerate(kind.commands):
            users.setdefault((p, c), []).append(k)
    parts = max((len(k.commands) for k in kinds), default=1)
    return tuple(
        tuple((c, commands[c].guard, tuple(ks)) for (q, c), ks in users.items()
              if q == p and not commands[c].always)
        for p in range(parts)
    )


def _kind_commands(kinds: Sequence[_Kind], none: int) -> IntArray:
    parts = max((len(k.commands) for k in kinds), default=1)
    table = np.full((len(kinds) + 1, parts), none, dtype=np.int64)
    for i, kind in enumerate(kinds):
        table[i, : len(kind.commands)] = kind.commands
    return table


def _branch_updates(
    commands: Sequence[CompiledCommand], kinds: Sequence[_Kind]
) -> list[list[tuple[int, ...]]]:
    """Per kind, each branch's update index per part (mixed radix, first part outermost)."""
    return [
        list(itertools.product(*(range(len(commands[c].updates)) for c in k.commands)))
        for k in kinds
    ]


class _Registry:
    """Distinct expressions (by compiled function) and the kinds that use each."""

    def __init__(self) -> None:
        self._index: dict[int, int] = {}
        self._exprs: list[tuple[CompiledExpr, bool]] = []
        self._users: list[set[int]] = []
        self._by_kind: dict[int, set[int]] = {}
        #: Each expression's source (None if not known): what a lookup tabulates.
        self.sources: list[Expr | None] = []

    def add(self, fn: CompiledExpr, kind: int, source: Expr | None = None) -> int:
        index = self._index.get(id(fn))
        if index is None:
            index = self._index[id(fn)] = len(self._exprs)
            self._exprs.append((fn, may_fail(fn)))
            self._users.append(set())
            self.sources.append(source)
        self._users[index].add(kind)
        self._by_kind.setdefault(kind, set()).add(index)
        return index

    def finish(self) -> tuple[LayerExpr, ...]:
        return tuple(
            LayerExpr(fn, risky, np.array(sorted(users), dtype=np.int64))
            for (fn, risky), users in zip(self._exprs, self._users, strict=True)
        )

    def kind_exprs(self, kinds: int) -> tuple[frozenset[int], ...]:
        return tuple(frozenset(self._by_kind.get(k, ())) for k in range(kinds))


def _values(
    program: Program,
    commands: Sequence[CompiledCommand],
    kinds: Sequence[_Kind],
    branches: Sequence[Sequence[tuple[int, ...]]],
) -> tuple[ValueTable, list[Expr | None]]:
    """Each branch kind's source row per variable (later parts' assignments win), and
    each value expression's source."""
    names = program.variable_names
    registry = _Registry()
    assigned = [
        _assigned(commands, kind, picks, (registry, k))
        for k, (kind, updates) in enumerate(zip(kinds, branches, strict=True))
        for picks in updates
    ]
    assigned.append({})  # the deadlock self-loop
    rows = np.tile(np.arange(len(names), dtype=np.int64), (len(assigned), 1))
    constants: dict[int, int] = {}
    for b, found in enumerate(assigned):
        for column, source in found.items():
            if isinstance(source, tuple):
                rows[b, column] = -1 - source[0]  # placed after the constants below
            else:
                rows[b, column] = len(names) + constants.setdefault(source, len(constants))
    exprs = rows < 0
    rows[exprs] = len(names) + len(constants) - 1 - rows[exprs]
    table = ValueTable(rows, np.array(list(constants), dtype=np.int64), registry.finish(),
                       registry.kind_exprs(len(kinds) + 1),
                       assigned=_assigned_entries(rows, program.lows, program.highs))
    return table, registry.sources


def _assigned_entries(
    rows: IntArray, lows: Sequence[int], highs: Sequence[int]
) -> AssignedEntries | None:
    """Per branch kind (a row of *rows*), the variables it assigns, padded (see
    :class:`AssignedEntries`); None if a range spans 2**63 or more, or there is no
    variable (a padding entry copies variable 0)."""
    spans = _spans(lows, highs)
    if spans is None or not len(lows):
        return None
    own = rows != np.arange(rows.shape[1])
    width = max(1, int(own.sum(axis=1).max(initial=0)))
    columns = np.zeros((rows.shape[0], width), dtype=np.int64)  # none: variable 0, copied
    for b, assigns in enumerate(own):
        found = np.flatnonzero(assigns)
        if found.size:
            columns[b, : found.size] = found
            columns[b, found.size :] = found[-1]  # repeated: the same value written again
    return AssignedEntries(columns, np.take_along_axis(rows, columns, axis=1),
                           np.asarray(lows, dtype=np.int64)[columns], spans[columns])


def _value_units(
    builder: LookupBuilder, sources: Sequence[Expr | None], exprs: Sequence[LayerExpr]
) -> tuple[list[int], IntArray]:
    """The units of the assignments' right-hand sides that *builder* can tabulate, and
    which expressions they are; risky ones are left to be evaluated where their kinds
    are enabled."""
    found: dict[int, int] = {}  # expression -> unit (equal expressions share one)
    for e, (source, expr) in enumerate(zip(sources, exprs, strict=True)):
        unit = builder.add(source) if source is not None and not expr.risky else None
        if unit is not None:
            found[e] = unit
    return list(found.values()), np.array(list(found), dtype=np.int64)


def _ranges(program: Program) -> dict[str, tuple[int, int]]:
    return dict(zip(program.variable_names,
                    zip(program.lows, program.highs, strict=True), strict=True))


def _assigned(
    commands: Sequence[CompiledCommand],
    kind: _Kind,
    picks: tuple[int, ...],
    user: tuple[_Registry, int],
) -> dict[int, int | tuple[int]]:
    """Column → constant or ``(expression index,)`` for one branch kind."""
    registry, k = user
    found: dict[int, int | tuple[int]] = {}
    for c, u in zip(kind.commands, picks, strict=True):
        update = commands[c].updates[u]
        sources = _sources(commands[c], u)
        for i, (column, rhs) in enumerate(update.assignments):
            constant = update.constants[i] if update.constants else None
            if constant is not None:
                found[column] = int(constant)
            else:
                found[column] = (registry.add(rhs, k, sources[i]),)
    return found


def _sources(command: CompiledCommand, u: int) -> list[Expr]:
    """The right-hand sides of update *u*'s compiled assignments: its written ones but
    ``(x'=x)``, which ``compile_program`` leaves out."""
    return [a.expr for a in command.command.updates[u].assignments
            if not (isinstance(a.expr, Ident) and a.expr.name == a.variable)]


def _factors(
    commands: Sequence[CompiledCommand],
    kinds: Sequence[_Kind],
    branches: Sequence[Sequence[tuple[int, ...]]],
) -> FactorTable:
    registry = _Registry()
    per_branch = [
        [_factor(commands[c], u, (registry, k)) for c, u in zip(kind.commands, picks, strict=True)]
        for k, (kind, updates) in enumerate(zip(kinds, branches, strict=True))
        for picks in updates
    ]
    per_branch.append([1.0])  # the deadlock self-loop
    exprs, kind_exprs = registry.finish(), registry.kind_exprs(len(kinds) + 1)
    if all(isinstance(f, float) for fs in per_branch for f in fs):
        constant = np.array([_product(fs) for fs in per_branch])
        return FactorTable(constant, np.empty((0, 0), dtype=np.int64), np.empty(0), exprs,
                           kind_exprs)
    parts = max(len(fs) for fs in per_branch)
    rows = np.zeros((len(per_branch), parts), dtype=np.int64)
    constants: dict[float, int] = {1.0: 0}
    for b, fs in enumerate(per_branch):
        for p, f in enumerate(fs):
            if isinstance(f, tuple):
                rows[b, p] = -1 - f[0]
            else:
                rows[b, p] = constants.setdefault(f, len(constants))
    negative = rows < 0
    rows[negative] = len(constants) - 1 - rows[negative]
    rows = rows[:, rows.any(axis=0)]  # a factor of 1.0 everywhere: nothing to multiply
    return FactorTable(None, rows, np.array(list(constants)[1:], dtype=np.float64), exprs,
                    kind_exprs)


def _factor(command: CompiledCommand, u: int, user: tuple[_Registry, int]) -> float | tuple[int]:
    registry, k = user
    update = command.updates[u]
    constant = update.constant_probability
    if constant is not None and constant >= 0:
        return float(constant)
    return (registry.add(update.probability, k),)


def _product(factors: Sequence[float | tuple[int]]) -> float:
    """The factors multiplied in part order from 1.0, as the group-by-group path does."""
    result = 1.0
    for f in factors:
        assert isinstance(f, float)
        result *= f
    return result


def _unchecked_sums(commands: Sequence[CompiledCommand], kinds: Sequence[_Kind]) -> frozenset[int]:
    """Kinds whose choice's probabilities are not statically known to sum to 1."""
    found = set()
    for k, kind in enumerate(kinds):
        totals = [commands[c].constant_total for c in kind.commands]
        if any(t is None for t in totals) or not abs(_product_of(totals) - 1.0) <= SUM_TOLERANCE:
            found.add(k)
    return frozenset(found)


def _product_of(values: Sequence[float | None]) -> float:
    return math.prod(v for v in values if v is not None)


def _action_kinds(kinds: Sequence[_Kind]) -> dict[str | None, IntArray]:
    found: dict[str | None, list[int]] = {}
    for k, kind in enumerate(kinds):
        found.setdefault(kind.action, []).append(k)
    return {a: np.array(ks, dtype=np.int64) for a, ks in found.items()}
