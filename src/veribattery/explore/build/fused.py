"""A whole BFS layer expanded over every choice group at once.

The group-by-group expansion (``successors``) costs a few dozen numpy calls per
group and layer; a model whose search is deep and narrow (the mission: 709
layers of ~250 states, 13 groups) spends most of its build in that per-call
overhead. A :class:`LayerPlan` instead enumerates the program's *choice kinds*
once (per group: one per command, or one per combination of one command per
synchronising module) and their *branch kinds* (one per combination of
updates), and tabulates statically, per branch kind, its probability factors
and which expression each variable takes. A layer then costs one pass:

1. every command guard on the frontier (a later synchronising part's only
   where one of its kinds is still alive), combined into a ``(kinds, n)``
   enabledness matrix, whose nonzeros read column by column are the choices
   already in the builder's order (source state, group, command combination);
2. each branch's kind id by ``repeat``;
3. per assigned variable, one gather from a small table whose rows are the
   evaluated right-hand sides (on the whole frontier, so shared sub-expressions
   hit the compile cache's memo) and the constants.

Expressions that may fail on some rows (division, ``mod``, ``pow``) are
evaluated only on the rows where a kind using them is enabled. Whenever
anything is unusual (an out-of-range target, a bad probability sum, a negative
probability, a float assigned to an integer, an evaluation error) the plan
gives up on the layer and the caller expands it group by group, which raises
the located error or decides the case exactly as before. Both give an
:class:`Expansion` (defined here, used by the builder for either path), bit for
bit the same: the same branches in the same order, probabilities multiplied in
the same order.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.errors import ModelError
from veribattery.explore.build.lookup import NarrowLookups, NarrowPath
from veribattery.explore.compile.expr import CompiledExpr

__all__ = [
    "SUM_TOLERANCE",
    "AssignedEntries",
    "Expansion",
    "FactorTable",
    "LayerBranches",
    "LayerExpr",
    "LayerPlan",
    "ValueTable",
]

SUM_TOLERANCE = 0.5e-6  # half the builder's: a borderline sum is left to the exact check
# 0-d arrays: a ufunc takes them for about half the cost of a scalar (see ``constant_node``)
_NO_PROBABILITY = np.asarray(0.0)
_NO_CHOICE = np.asarray(0, dtype=np.int64)


@dataclass(frozen=True, slots=True)
class Expansion:
    """The branches out of a frontier, in order of source state, zero-probability ones dropped.

    :param source: frontier-local source of each kept branch.
    :param targets: successor rows of the kept branches.
    :param probability: probability of each kept branch (1/n choice weighting applied).
    :param choices: number of enabled choices per frontier state.
    :param action_choices: per rewarded action, its number of choices per state.
    :param dropped: positions of the dropped branches before dropping.
    :param branches: number of branches before dropping.
    """

    source: IntArray
    targets: IntArray
    probability: FloatArray
    choices: IntArray
    action_choices: dict[str | None, IntArray]
    dropped: IntArray
    branches: int


@dataclass(frozen=True, slots=True)
class LayerBranches:
    """Every branch out of a frontier, zero-probability ones included, before any 1/n
    weighting, by source state, then choice kind, then branch. Per choice (a deadlock's
    self-loop included): *choice_source*, *kind* (``plan.kinds``: the self-loop) and
    *widths*, its branches; *enabled* is ``(kinds + 1, n)``, *choices* per state, *alive*
    per kind (empty if not needed), *source* per branch."""

    enabled: BoolArray
    choices: IntArray
    choice_source: IntArray
    kind: IntArray
    widths: IntArray
    alive: list[bool]
    source: IntArray
    targets: IntArray
    probability: FloatArray


@dataclass(frozen=True, slots=True)
class LayerExpr:
    """An expression evaluated per layer: on the frontier, or on *kinds*' rows if risky."""

    fn: CompiledExpr
    risky: bool
    kinds: IntArray


@dataclass(frozen=True, slots=True)
class ValueTable:
    """Where each branch kind's new variable values come from: rows of a per-layer table.

    The table has one row per variable (its source value), then one per integer
    constant in *constants*, then one per expression in *exprs*; *rows* is
    ``(branch kinds, variables)``: each variable's row for each branch kind, so
    that all the targets of a layer are one gather.
    """

    rows: IntArray
    constants: IntArray
    exprs: tuple[LayerExpr, ...]
    kind_exprs: tuple[frozenset[int], ...]
    #: The expressions needed per set of present kinds (see ``_needed``).
    needed: dict[tuple[int, ...], tuple[int, ...]] = field(default_factory=dict, compare=False)
    #: The variables each branch kind assigns (None if a range spans 2**63 or more).
    assigned: AssignedEntries | None = None


@dataclass(frozen=True, slots=True)
class AssignedEntries:
    """Per branch kind ``(branch kinds, K)``, the *columns* of the variables it assigns,
    their *rows* of the layer's value table, their *lows* and their ranges' *spans*
    (uint64), padded: a padding entry repeats one of the kind's entries (or copies
    variable 0 from the source), so writing it changes nothing.

    A branch copies its source state and overwrites these: crowds' updates assign
    three of its 32 variables, so three values per branch are gathered and checked.
    """

    columns: IntArray
    rows: IntArray
    lows: IntArray
    spans: np.ndarray


@dataclass(frozen=True, slots=True)
class FactorTable:
    """Branch probabilities: constants per branch kind, or per-part factor rows.

    *constant* is set when every factor of every branch kind is a constant.
    Otherwise *rows* is ``(branch kinds, parts)``: each part's factor as a row of a
    per-layer table whose row 0 is 1.0, then *constants*, then *exprs* (part
    positions where every factor is 1.0 are left out).
    """

    constant: FloatArray | None
    rows: IntArray
    constants: FloatArray
    exprs: tuple[LayerExpr, ...]
    kind_exprs: tuple[frozenset[int], ...]
    needed: dict[tuple[int, ...], tuple[int, ...]] = field(default_factory=dict, compare=False)


@dataclass(frozen=True, slots=True)
class LayerPlan:
    """The static tables of a program's fused layer expansion (see the module doc)."""

    #: Per part position: (command index, guard, kinds using it) of its non-trivial guards.
    guards: tuple[tuple[tuple[int, CompiledExpr, tuple[int, ...]], ...], ...]
    commands: int
    kind_commands: IntArray  # (kinds + 1, parts): command per part, ``commands`` = none
    widths: IntArray  # branches per kind; the last kind is the deadlock self-loop
    starts: IntArray  # first branch kind of each kind
    values: ValueTable
    factors: FactorTable
    unchecked_sums: frozenset[int]  # kinds whose probabilities need a run-time sum check
    action_kinds: dict[str | None, IntArray]
    lows: IntArray
    highs: IntArray
    spans: np.ndarray | None  # highs - lows as uint64, None if one reaches 2**63
    #: Per set of rewarded actions: those with kinds, each with its kinds (see
    #: ``_action_choices``).
    members: dict[frozenset[str | None], list[tuple[str | None, list[int]]]] = field(
        default_factory=dict, compare=False
    )
    #: The lookups of a deep search's narrow layers (see ``lookup``), if any.
    narrow: NarrowPath | None = field(default=None, compare=False)

    @property
    def kinds(self) -> int:
        """Choice kinds, the deadlock self-loop excluded."""
        return int(self.widths.size) - 1

    def expand(self, states: IntArray, rewarded: set[str | None]) -> Expansion | None:
        """Every branch out of *states*, or None if the layer needs the group-by-group path."""
        try:
            return _expand(self, states, rewarded)
        except ModelError:
            return None

    def branches(self, states: IntArray) -> LayerBranches | None:
        """Every choice and branch out of *states* (an MDP's rows), or None if the layer
        needs the group-by-group path."""
        try:
            return _branches(self, states, set())
        except ModelError:
            return None


# ---------------------------------------------------------------------------
# Expanding a layer
# ---------------------------------------------------------------------------


def _expand(plan: LayerPlan, states: IntArray, rewarded: set[str | None]) -> Expansion | None:
    layer = _branches(plan, states, rewarded)
    if layer is None:
        return None
    source, targets, probability = layer.source, layer.targets, layer.probability
    total = source.size
    if layer.kind.size > states.shape[0]:  # some state has several choices (or n = 0)
        probability /= np.maximum(layer.choices, 1)[source]
    keep = probability > _NO_PROBABILITY
    dropped = np.empty(0, dtype=np.int64)
    if np.count_nonzero(keep) < keep.size:
        dropped = np.flatnonzero(~keep)
        source, targets, probability = source[keep], targets[keep], probability[keep]
    actions = _action_choices(plan, layer.enabled, layer.alive, rewarded)
    return Expansion(source, targets, probability, layer.choices, actions, dropped, total)


def _branches(plan: LayerPlan, states: IntArray,
              rewarded: set[str | None]) -> LayerBranches | None:
    lookups = plan.narrow.lookups(states.shape[0]) if plan.narrow is not None else None
    looked = None if lookups is None else (lookups, lookups.lookup.evaluate(states))
    enabled, choices = _enabled(plan, states, looked)
    src, kind = _positions(enabled)
    alive: list[bool] = (np.logical_or.reduce(enabled, axis=1).tolist()
                         if _reads_kinds(plan, lookups, rewarded) else [])
    present = [k for k, on in enumerate(alive) if on]
    widths = plan.widths[kind]
    total = int(widths.sum())
    if total == src.size:  # one branch per choice
        branch, source, firsts = plan.starts[kind], src, np.arange(total)
    else:
        firsts = np.cumsum(widths) - widths
        branch = np.repeat(plan.starts[kind] - firsts, widths) + np.arange(total)
        source = np.repeat(src, widths)
    targets = _targets(plan.values, (states, looked), enabled, present, (branch, source))
    probability = _probabilities(plan.factors, states, enabled, present, (branch, source))
    if probability is None or not _sums_ok(plan, present, probability, firsts, kind):
        return None
    checked = plan.values.assigned is not None and looked is None  # by ``_targets``
    if targets is None or (not checked and _out_of_range(plan, targets)):
        return None
    return LayerBranches(enabled, choices, src, kind, widths, alive, source, targets,
                         probability)


#: A narrow layer's lookups and their values on its frontier ``(units, n)``.
_Looked = tuple[NarrowLookups, IntArray]


def _reads_kinds(
    plan: LayerPlan, lookups: NarrowLookups | None, rewarded: set[str | None]
) -> bool:
    """Whether a layer needs to know which kinds are enabled in some state: to evaluate
    the expressions those kinds use, check their sums or count the rewarded actions'
    choices (a narrow layer of a program whose expressions are all looked up and
    probabilities constant needs none of it)."""
    looked_up = len(lookups.looked_up) if lookups is not None else 0
    return bool(looked_up < len(plan.values.exprs) or plan.factors.constant is None
                or plan.unchecked_sums or rewarded)


def _enabled(
    plan: LayerPlan, states: IntArray, looked: _Looked | None = None
) -> tuple[BoolArray, IntArray]:
    """Enabledness ``(kinds + 1, n)`` (the last row: deadlock) and choices per state.

    Kind-major rows keep every reduction over contiguous memory. Guards are
    evaluated part by part, and a guard of a later part only where one of its
    kinds is still enabled in some state, as the group-by-group path does
    (``successors``: a group whose first modules enable nothing stops there), so
    that both paths evaluate, and may fail on, the same guards.
    """
    tabulated = looked[0].guards if looked is not None else None
    if looked is not None and tabulated is not None and tabulated.kinds is not None:
        enabled = tabulated.enabled(looked[1])  # every guard looked up: one gather
    else:
        enabled = _evaluated(plan, states, looked)
    choices = np.add.reduce(enabled[: plan.kinds], axis=0, dtype=np.int64)
    np.equal(choices, _NO_CHOICE, out=enabled[plan.kinds])
    return enabled, choices


def _evaluated(plan: LayerPlan, states: IntArray, looked: _Looked | None) -> BoolArray:
    """:func:`_enabled`'s matrix (the last row unset), part by part; the tabulated guards
    (if any) read from the *looked* up values: they have a value in every state of
    the ranges, so reading them where a part before enables nothing raises nothing."""
    tabulated = looked[0].guards if looked is not None else None
    if looked is not None and tabulated is not None:
        guards, evaluated = tabulated.guards(looked[1]), tabulated.residual
    else:
        guards = np.ones((plan.commands + 1, states.shape[0]), dtype=bool)  # always-true stay
        evaluated = plan.guards
    table = plan.kind_commands
    for i, guard, _ in evaluated[0]:
        guards[i] = guard(states)
    enabled = guards[table[:, 0]]
    for p in range(1, len(evaluated)):
        alive = np.logical_or.reduce(enabled, axis=1).tolist()
        for i, guard, kinds in evaluated[p]:
            if any(map(alive.__getitem__, kinds)):
                guards[i] = guard(states)
        enabled &= guards[table[:, p]]
    return enabled


def _positions(enabled: BoolArray) -> tuple[IntArray, IntArray]:
    """Source state and kind of every enabled choice, in (source, kind) order."""
    source, kind = enabled.T.nonzero()  # row-major over the transpose: by source first
    return source, kind


def _out_of_range(plan: LayerPlan, targets: IntArray) -> bool:
    """Whether some target leaves a variable's range: ``target - low`` read unsigned
    exceeds the range's span exactly when the target is below *low* or above *high*
    (the subtraction wraps modulo 2**64; spans are below 2**63)."""
    if plan.spans is None:
        return bool((targets < plan.lows).any() or (targets > plan.highs).any())
    offsets = targets - plan.lows
    return bool(np.count_nonzero(offsets.view(np.uint64) > plan.spans))


def _fill(
    table: np.ndarray,
    base: int,
    exprs: ValueTable | FactorTable,
    states: IntArray,
    enabled: BoolArray,
    present: list[int],
    skip: frozenset[int] = frozenset(),
) -> None:
    """Evaluate the expressions the present kinds need into rows ``base + e`` of *table*,
    but those in *skip* (filled in already).

    :raises ModelError: an integer table receives floats (the slow path reports it).
    """
    integer = table.dtype.kind == "i"
    for e in _needed(exprs, present):
        if e in skip:
            continue
        expr = exprs.exprs[e]
        if expr.risky:  # only where a kind using it is enabled
            rows = np.flatnonzero(np.logical_or.reduce(enabled[expr.kinds], axis=0))
            value = np.asarray(expr.fn(states[rows]))
        else:
            rows, value = None, np.asarray(expr.fn(states))
        if integer and value.dtype.kind == "f":
            raise ModelError("non-integer assignment")
        if rows is None:
            table[base + e] = value
        else:
            table[base + e, rows] = value


#: Sets of present kinds remembered per table of expressions (a few per model in practice).
_NEEDED_KEEP = 1 << 12


def _needed(exprs: ValueTable | FactorTable, present: list[int]) -> tuple[int, ...]:
    """The expressions used by the *present* kinds, remembered per set of kinds."""
    key = tuple(present)
    found = exprs.needed.get(key)
    if found is None:
        if len(exprs.needed) >= _NEEDED_KEEP:
            exprs.needed.clear()
        union = frozenset().union(*(exprs.kind_exprs[k] for k in present))
        found = exprs.needed[key] = tuple(sorted(union))
    return found


def _gather(table: np.ndarray, rows: IntArray, at: tuple[IntArray, IntArray]) -> np.ndarray:
    """``table[rows[branch, j], source]`` for every branch and column *j*, in one take."""
    branch, source = at
    scaled: IntArray = rows * table.shape[1]  # on the few branch kinds, not per branch
    index = scaled[branch]
    index += source[:, None]
    gathered: np.ndarray = table.ravel().take(index)
    return gathered


def _targets(
    values: ValueTable,
    over: tuple[IntArray, _Looked | None],
    enabled: BoolArray,
    present: list[int],
    at: tuple[IntArray, IntArray],
) -> IntArray | None:
    """The successor rows of the branches *at* (branch kind, source); None if a value
    assigned leaves its variable's range (checked here when the plan lists the
    variables each kind assigns, else by the caller)."""
    states, looked = over
    n, width = states.shape
    base = width + values.constants.size
    assigned = values.assigned if looked is None else None  # narrow: one gather, fewer calls
    table = np.empty((base + len(values.exprs), n), dtype=np.int64)
    if assigned is None:
        table[:width] = states.T
    else:  # only a kind that assigns nothing reads a variable's row: variable 0's
        table[0] = states[:, 0]
    table[width:base] = values.constants[:, None]
    skip: frozenset[int] = frozenset()
    if looked is not None:
        # Every tabulated right-hand side, present kind or not: none can fail.
        lookups, values_looked = looked
        table[lookups.value_rows] = values_looked[lookups.first_value :]
        skip = lookups.looked_up
    _fill(table, base, values, states, enabled, present, skip)
    if assigned is None:
        gathered: IntArray = _gather(table, values.rows, at)
        return gathered
    branch, source = at
    new = _gather(table, assigned.rows, at)
    # ``value - low`` read unsigned exceeds the span exactly when the value is below
    # *low* or above *high* (it wraps modulo 2**64; spans are below 2**63).
    offsets = new - assigned.lows[branch]
    if np.count_nonzero(offsets.view(np.uint64) > assigned.spans[branch]):
        return None
    # The source's values (in range), then the new ones written at their flat positions.
    targets: IntArray = np.take(states, source, axis=0)
    where = assigned.columns[branch]
    where += (np.arange(source.size) * width)[:, None]
    targets.ravel()[where] = new
    return targets


def _probabilities(
    factors: FactorTable,
    states: IntArray,
    enabled: BoolArray,
    present: list[int],
    at: tuple[IntArray, IntArray],
) -> FloatArray | None:
    """Branch probabilities before the 1/n weighting; None if a factor is negative."""
    if factors.constant is not None:
        constant: FloatArray = factors.constant[at[0]]
        return constant
    base = 1 + factors.constants.size
    table = np.empty((base + len(factors.exprs), states.shape[0]), dtype=np.float64)
    table[0] = 1.0
    table[1:base] = factors.constants[:, None]
    _fill(table, base, factors, states, enabled, present)
    gathered = _gather(table, factors.rows, at)
    if gathered.min(initial=0.0) < 0:
        return None
    probability: FloatArray = gathered[:, 0].copy()
    for p in range(1, gathered.shape[1]):  # in part order, as the group-by-group path
        probability *= gathered[:, p]
    return probability


def _sums_ok(
    plan: LayerPlan, present: list[int], probability: FloatArray, firsts: IntArray, kind: IntArray
) -> bool:
    if plan.unchecked_sums.isdisjoint(present) or probability.size == 0:
        return True
    sums = np.add.reduceat(probability, firsts)
    live = kind < plan.kinds
    return bool(np.all(np.abs(sums[live] - 1.0) <= SUM_TOLERANCE))


def _action_choices(
    plan: LayerPlan, enabled: BoolArray, alive: list[bool], rewarded: set[str | None]
) -> dict[str | None, IntArray]:
    """Per rewarded action with a choice in this layer, its number of choices per state."""
    found: dict[str | None, IntArray] = {}
    for action, kinds in _members(plan, frozenset(rewarded)):
        live = [k for k in kinds if alive[k]]
        if len(live) == 1:  # 0/1 per state: the kind's row as it is
            found[action] = enabled[live[0]].view(np.uint8)
        elif live:
            found[action] = np.add.reduce(enabled[live], axis=0, dtype=np.int64)
    return found


def _members(
    plan: LayerPlan, rewarded: frozenset[str | None]
) -> list[tuple[str | None, list[int]]]:
    """The rewarded actions that have kinds, with their kinds."""
    found = plan.members.get(rewarded)
    if found is None:
        found = plan.members[rewarded] = [
            (a, plan.action_kinds[a].tolist()) for a in plan.action_kinds if a in rewarded
        ]
    return found
