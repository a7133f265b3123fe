"""A whole BFS layer expanded over every choice group at once.

The group-by-group expansion (``successors``) costs a few dozen numpy calls per
group and layer; a model whose search is deep and narrow (the mission: 709
layers of ~250 states, 13 groups) spends most of its build in that per-call
overhead. A :class:`LayerPlan` instead enumerates the program's *choice kinds*
once (per group: one per command, or one per combination of one command per
synchronising module) and their *branch kinds* (one per combination of
updates), and tabulates statically, per branch kind, its probability factors
and which expression each variable takes. A layer then costs one pass:

1. every command guard on the frontier, combined into an ``(n, kinds)``
   enabledness matrix, whose row-major nonzeros are the choices already in the
   builder's order (source state, group, command combination);
2. each branch's kind id by ``repeat``;
3. per assigned variable, one gather from a small table whose rows are the
   evaluated right-hand sides (on the whole frontier, so shared sub-expressions
   hit the compile cache's memo) and the constants.

Expressions that may fail on some rows (division, ``mod``, ``pow``) are
evaluated only on the rows where a kind using them is enabled. Whenever
anything is unusual (an out-of-range target, a bad probability sum, a negative
probability, a float assigned to an integer, an evaluation error) the plan
gives up on the layer and the caller expands it group by group, which raises
the located error or decides the case exactly as before. The result is the
same :class:`~veribattery.explore.builder.Expansion`, bit for bit: the same
branches in the same order, probabilities multiplied in the same order.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.errors import ModelError
from veribattery.explore.compile import CompiledExpr
from veribattery.explore.program import CompiledCommand, Program
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import Binary, Call, Expr

__all__ = ["FusedExpansion", "LayerPlan", "plan_layers"]

#: Plans with more choice or branch kinds than this are not built (the enabledness
#: matrix has one column per choice kind): such programs expand group by group.
MAX_KINDS = 512
MAX_BRANCH_KINDS = 4096
_TOLERANCE = 0.5e-6  # half the builder's: a borderline sum is left to the exact check


@dataclass(frozen=True, slots=True)
class FusedExpansion:
    """The branches out of a frontier (fields as the builder's ``Expansion``)."""

    source: IntArray
    targets: IntArray
    probability: FloatArray
    choices: IntArray
    action_choices: dict[str | None, IntArray]
    dropped: IntArray
    branches: int


@dataclass(frozen=True, slots=True)
class _Expr:
    """An expression evaluated per layer: on the frontier, or on *kinds*' rows if risky."""

    fn: CompiledExpr
    risky: bool
    kinds: IntArray


@dataclass(frozen=True, slots=True)
class _Column:
    """How one variable is set: per branch kind, a row of the layer's value table.

    Row 0 is the source value; then one row per entry of *sources*, an ``int``
    constant or an index into the plan's expressions.
    """

    column: int
    rows: IntArray
    sources: tuple[int | tuple[int], ...]
    kinds: frozenset[int]  # the choice kinds that assign this column


@dataclass(frozen=True, slots=True)
class _Factors:
    """Branch probabilities: constants per branch kind, or per-part factor rows.

    *constant* is set when every factor of every branch kind is a constant.
    Otherwise *rows* holds, per part position, each branch kind's row in a table
    whose row 0 is 1.0, then *sources* (float constants or expression indices).
    """

    constant: FloatArray | None
    rows: tuple[IntArray, ...]
    sources: tuple[float | tuple[int], ...]


@dataclass(frozen=True, slots=True)
class LayerPlan:
    """The static tables of a program's fused layer expansion (see the module doc)."""

    guards: tuple[tuple[int, CompiledExpr], ...]  # (command index, guard), non-trivial ones
    commands: int
    kind_commands: IntArray  # (kinds + 1, parts): command per part, ``commands`` = none
    widths: IntArray  # branches per kind; the last kind is the deadlock self-loop
    starts: IntArray  # first branch kind of each kind
    exprs: tuple[_Expr, ...]
    kind_exprs: tuple[frozenset[int], ...]
    columns: tuple[_Column, ...]
    factors: _Factors
    unchecked_sums: frozenset[int]  # kinds whose probabilities need a run-time sum check
    action_kinds: dict[str | None, IntArray]
    lows: IntArray
    highs: IntArray
    #: Per set of rewarded actions, those with kinds and their kind membership matrix.
    members: dict[frozenset[str | None], tuple[list[str | None], IntArray]] = field(
        default_factory=dict, compare=False
    )

    @property
    def kinds(self) -> int:
        """Choice kinds, the deadlock self-loop excluded."""
        return int(self.widths.size) - 1

    def expand(self, states: IntArray, rewarded: set[str | None]) -> FusedExpansion | None:
        """Every branch out of *states*, or None if the layer needs the group-by-group path."""
        try:
            return _expand(self, states, rewarded)
        except ModelError:
            return None


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
    registry = _Registry()
    columns = _columns(program, commands, kinds, branches, registry)
    factors = _factors(commands, kinds, branches, registry)
    return LayerPlan(
        guards=tuple((i, c.guard) for i, c in enumerate(commands) if not c.always),
        commands=len(commands),
        kind_commands=_kind_commands(kinds, len(commands)),
        widths=np.array(widths, dtype=np.int64),
        starts=np.cumsum([0, *widths[:-1]]).astype(np.int64),
        exprs=registry.finish(),
        kind_exprs=registry.kind_exprs(len(kinds) + 1),
        columns=columns,
        factors=factors,
        unchecked_sums=_unchecked_sums(commands, kinds),
        action_kinds=_action_kinds(kinds),
        lows=np.array(program.lows, dtype=np.int64),
        highs=np.array(program.highs, dtype=np.int64),
    )


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

    def add(self, fn: CompiledExpr, expr: Expr, kind: int) -> int:
        index = self._index.get(id(fn))
        if index is None:
            index = self._index[id(fn)] = len(self._exprs)
            self._exprs.append((fn, _risky(expr)))
            self._users.append(set())
        self._users[index].add(kind)
        self._by_kind.setdefault(kind, set()).add(index)
        return index

    def finish(self) -> tuple[_Expr, ...]:
        return tuple(
            _Expr(fn, risky, np.array(sorted(users), dtype=np.int64))
            for (fn, risky), users in zip(self._exprs, self._users, strict=True)
        )

    def kind_exprs(self, kinds: int) -> tuple[frozenset[int], ...]:
        return tuple(frozenset(self._by_kind.get(k, ())) for k in range(kinds))


def _risky(expr: Expr) -> bool:
    """Whether evaluating *expr* may raise on some rows (as ``compile`` marks it)."""
    return any(
        (isinstance(node, Binary) and node.op == "/")
        or (isinstance(node, Call) and node.func in ("pow", "mod"))
        for node in walk(expr)
    )


def _columns(
    program: Program,
    commands: Sequence[CompiledCommand],
    kinds: Sequence[_Kind],
    branches: Sequence[Sequence[tuple[int, ...]]],
    registry: _Registry,
) -> tuple[_Column, ...]:
    """Per variable, each branch kind's source of its new value (later parts win)."""
    total = sum(len(b) for b in branches) + 1
    rows = {c: np.zeros(total, dtype=np.int64) for c in range(len(program.variable_names))}
    sources: dict[int, dict[int | tuple[int], int]] = {c: {} for c in rows}
    users: dict[int, set[int]] = {c: set() for c in rows}
    b = 0
    for k, (kind, updates) in enumerate(zip(kinds, branches, strict=True)):
        for picks in updates:
            assigned = _assigned(program.variable_names, commands, kind, picks, (registry, k))
            for c, source in assigned.items():
                rows[c][b] = sources[c].setdefault(source, len(sources[c]) + 1)
                users[c].add(k)
            b += 1
    return tuple(
        _Column(c, rows[c], tuple(sources[c]), frozenset(users[c])) for c in rows if sources[c]
    )


def _assigned(
    names: Sequence[str],
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
        exprs = {a.variable: a.expr for a in commands[c].command.updates[u].assignments}
        for i, (column, rhs) in enumerate(update.assignments):
            constant = update.constants[i] if update.constants else None
            if constant is not None:
                found[column] = int(constant)
            else:
                found[column] = (registry.add(rhs, exprs[names[column]], k),)
    return found


def _factors(
    commands: Sequence[CompiledCommand],
    kinds: Sequence[_Kind],
    branches: Sequence[Sequence[tuple[int, ...]]],
    registry: _Registry,
) -> _Factors:
    parts = max((len(k.commands) for k in kinds), default=1)
    per_branch: list[list[float | tuple[int]]] = []
    for k, (kind, updates) in enumerate(zip(kinds, branches, strict=True)):
        for picks in updates:
            per_branch.append([_factor(commands[c], u, registry, k)
                               for c, u in zip(kind.commands, picks, strict=True)])
    per_branch.append([1.0])  # the deadlock self-loop
    if all(isinstance(f, float) for fs in per_branch for f in fs):
        return _Factors(np.array([_product(fs) for fs in per_branch]), (), ())
    sources: dict[float | tuple[int], int] = {1.0: 0}
    rows = [np.zeros(len(per_branch), dtype=np.int64) for _ in range(parts)]
    for b, fs in enumerate(per_branch):
        for p, f in enumerate(fs):
            rows[p][b] = sources.setdefault(f, len(sources))
    return _Factors(None, tuple(r for r in rows if r.any()), tuple(sources)[1:])


def _factor(command: CompiledCommand, u: int, registry: _Registry, k: int) -> float | tuple[int]:
    update = command.updates[u]
    constant = update.constant_probability
    if constant is not None and constant >= 0:
        return float(constant)
    return (registry.add(update.probability, command.command.updates[u].probability, k),)


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
        if any(t is None for t in totals) or not abs(_product_of(totals) - 1.0) <= _TOLERANCE:
            found.add(k)
    return frozenset(found)


def _product_of(values: Sequence[float | None]) -> float:
    return math.prod(v for v in values if v is not None)


def _action_kinds(kinds: Sequence[_Kind]) -> dict[str | None, IntArray]:
    found: dict[str | None, list[int]] = {}
    for k, kind in enumerate(kinds):
        found.setdefault(kind.action, []).append(k)
    return {a: np.array(ks, dtype=np.int64) for a, ks in found.items()}


# ---------------------------------------------------------------------------
# Expanding a layer
# ---------------------------------------------------------------------------


def _expand(plan: LayerPlan, states: IntArray, rewarded: set[str | None]) -> FusedExpansion | None:
    enabled, choices = _enabled(plan, states)
    src, kind = np.nonzero(enabled)
    present = np.flatnonzero(enabled.any(axis=0)).tolist()
    widths = plan.widths[kind]
    total = int(widths.sum())
    if total == src.size:  # one branch per choice
        branch, source, firsts = plan.starts[kind], src, np.arange(total)
    else:
        firsts = np.cumsum(widths) - widths
        branch = np.repeat(plan.starts[kind] - firsts, widths) + np.arange(total)
        source = np.repeat(src, widths)
    values = _evaluate(plan, states, enabled, present)
    if values is None:
        return None
    targets = _targets(plan, states, values, present, branch, source)
    probability = _probabilities(plan, states, values, branch, source)
    if probability is None or not _sums_ok(plan, present, probability, firsts, kind):
        return None
    if (targets < plan.lows).any() or (targets > plan.highs).any():
        return None
    if choices.max(initial=0) > 1:
        probability /= np.maximum(choices, 1)[source]
    keep = probability > 0
    dropped = np.empty(0, dtype=np.int64)
    if not keep.all():
        dropped = np.flatnonzero(~keep)
        source, targets, probability = source[keep], targets[keep], probability[keep]
    actions = _action_choices(plan, enabled, rewarded)
    return FusedExpansion(source, targets, probability, choices, actions, dropped, total)


def _enabled(plan: LayerPlan, states: IntArray) -> tuple[BoolArray, IntArray]:
    """Enabledness ``(n, kinds + 1)`` (the last column: deadlock) and choices per state."""
    guards = np.ones((states.shape[0], plan.commands + 1), dtype=bool)  # always-true ones stay
    for i, guard in plan.guards:
        guards[:, i] = guard(states)
    table = plan.kind_commands
    enabled = guards[:, table[:, 0]]
    for p in range(1, table.shape[1]):
        enabled &= guards[:, table[:, p]]
    choices = np.count_nonzero(enabled[:, : plan.kinds], axis=1).astype(np.int64)
    enabled[:, plan.kinds] = choices == 0
    return enabled, choices


def _evaluate(
    plan: LayerPlan, states: IntArray, enabled: BoolArray, present: list[int]
) -> dict[int, np.ndarray] | None:
    """The expressions the present kinds need; None if an assignment yields floats."""
    needed = frozenset().union(*(plan.kind_exprs[k] for k in present))
    values: dict[int, np.ndarray] = {}
    for e in needed:
        expr = plan.exprs[e]
        if not expr.risky:
            values[e] = np.asarray(expr.fn(states))
            continue
        rows = np.flatnonzero(enabled[:, expr.kinds].any(axis=1))
        part = np.asarray(expr.fn(states[rows]))
        full = np.zeros(states.shape[0], dtype=part.dtype)
        full[rows] = part
        values[e] = full
    return values


def _targets(
    plan: LayerPlan,
    states: IntArray,
    values: dict[int, np.ndarray],
    present: list[int],
    branch: IntArray,
    source: IntArray,
) -> IntArray:
    targets = states[source]
    n = states.shape[0]
    kinds = set(present)
    for column in plan.columns:
        if kinds.isdisjoint(column.kinds):
            continue
        table = np.empty((len(column.sources) + 1, n), dtype=np.int64)
        table[0] = states[:, column.column]
        for r, value in enumerate(column.sources, start=1):
            if isinstance(value, tuple):
                evaluated = values.get(value[0])
                if evaluated is None:
                    continue  # no present kind uses it: the row is never gathered
                if evaluated.dtype.kind == "f":
                    raise ModelError("non-integer assignment")  # the slow path locates it
                table[r] = evaluated
            else:
                table[r] = value
        index = column.rows[branch] * n
        index += source
        targets[:, column.column] = table.ravel().take(index)
    return targets


def _probabilities(
    plan: LayerPlan,
    states: IntArray,
    values: dict[int, np.ndarray],
    branch: IntArray,
    source: IntArray,
) -> FloatArray | None:
    """Branch probabilities before the 1/n weighting; None if a factor is negative."""
    factors = plan.factors
    if factors.constant is not None:
        return factors.constant[branch]
    n = states.shape[0]
    table = np.ones((len(factors.sources) + 1, n), dtype=np.float64)
    for r, value in enumerate(factors.sources, start=1):
        if isinstance(value, tuple):
            evaluated = values.get(value[0])
            if evaluated is not None:
                table[r] = evaluated
        else:
            table[r] = value
    flat = table.ravel()
    probability: FloatArray | None = None
    for rows in factors.rows:
        index = rows[branch] * n
        index += source
        factor = flat.take(index)
        if factor.min(initial=0.0) < 0:
            return None
        probability = factor if probability is None else probability * factor
    return np.ones(branch.size) if probability is None else probability


def _sums_ok(
    plan: LayerPlan, present: list[int], probability: FloatArray, firsts: IntArray, kind: IntArray
) -> bool:
    if plan.unchecked_sums.isdisjoint(present) or probability.size == 0:
        return True
    sums = np.add.reduceat(probability, firsts)
    live = kind < plan.kinds
    return bool(np.all(np.abs(sums[live] - 1.0) <= _TOLERANCE))


def _action_choices(
    plan: LayerPlan, enabled: BoolArray, rewarded: set[str | None]
) -> dict[str | None, IntArray]:
    """Per rewarded action with a choice in this layer, its number of choices per state."""
    actions, members = _members(plan, frozenset(rewarded))
    if not actions:
        return {}
    counts: IntArray = enabled.view(np.uint8) @ members  # one product for every action
    present = np.count_nonzero(counts, axis=0) > 0
    return {a: counts[:, i] for i, a in enumerate(actions) if present[i]}


def _members(
    plan: LayerPlan, rewarded: frozenset[str | None]
) -> tuple[list[str | None], IntArray]:
    """The rewarded actions that have kinds, and a ``(kinds + 1, actions)`` 0/1 matrix."""
    found = plan.members.get(rewarded)
    if found is None:
        actions = [a for a in plan.action_kinds if a in rewarded]
        matrix = np.zeros((plan.kinds + 1, len(actions)), dtype=np.int64)
        for i, action in enumerate(actions):
            matrix[plan.action_kinds[action], i] = 1
        found = plan.members[rewarded] = (actions, matrix)
    return found
