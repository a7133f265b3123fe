"""A flat model compiled for exploration: commands as numpy functions, grouped into choices.

A *choice group* is one source of choices. Each module's unlabelled commands form
a group with a single part (every enabled command is its own choice). Each action
label forms a group with one part per module whose alphabet contains it; a joint
choice picks one enabled command from every part.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

from veribattery.errors import PrismSemanticError, Span
from veribattery.explore.compile.bounds import value_bounds
from veribattery.explore.compile.equalities import EqualityIndex, equality_index
from veribattery.explore.compile.expr import (
    CompileCache,
    CompiledExpr,
    compile_expr,
    constant_value,
)
from veribattery.lang.nodes import Command, Expr, FlatModel, FlatModule, Ident, Update
from veribattery.lang.semantics import require_flat

__all__ = [
    "ChoiceGroup",
    "CompiledCommand",
    "CompiledUpdate",
    "Program",
    "compile_program",
    "with_probabilities",
]


@dataclass(frozen=True, slots=True)
class CompiledUpdate:
    """One probabilistic branch: its probability and ``(column, right-hand side)`` pairs.

    *constant_probability* is set when the probability folds to a constant;
    *unchecked* lists the columns whose right-hand side provably stays in range
    (interval analysis), so the explorer need not check them per state.
    """

    probability: CompiledExpr
    assignments: tuple[tuple[int, CompiledExpr], ...]
    span: Span
    constant_probability: float | None = None
    unchecked: frozenset[int] = frozenset()
    #: Per assignment, its value if it folds to an integer constant (else None);
    #: empty when none was computed.
    constants: tuple[int | None, ...] = ()


@dataclass(frozen=True, slots=True)
class CompiledCommand:
    """A command of module *module*, compiled."""

    module: str
    command: Command
    guard: CompiledExpr
    updates: tuple[CompiledUpdate, ...]
    always: bool = False  # the guard folds to true
    #: The sum of the update probabilities if they are all constants, else None.
    constant_total: float | None = None

    @property
    def span(self) -> Span:
        """Where the command is written."""
        return self.command.span


@dataclass(frozen=True, slots=True)
class ChoiceGroup:
    """Commands that produce choices together: one part per participating module."""

    action: str | None
    parts: tuple[tuple[CompiledCommand, ...], ...]
    #: Per part, the index of its guards where they only fix variables to constants
    #: (:mod:`~veribattery.explore.compile.equalities`), else None; () for none at all.
    indexes: tuple[EqualityIndex | None, ...] = field(default=(), compare=False)

    def index(self, part: int) -> EqualityIndex | None:
        """The equality index of part *part*, if it has one."""
        return self.indexes[part] if part < len(self.indexes) else None


@dataclass(frozen=True, slots=True)
class Program:
    """Everything the explorer evaluates, compiled once."""

    variable_names: tuple[str, ...]
    lows: tuple[int, ...]
    highs: tuple[int, ...]
    groups: tuple[ChoiceGroup, ...]
    #: Some guards or assignments are evaluated in rationals (``exact.program``): the
    #: functions are then not all those the commands' expressions compile to.
    exact: bool = False


def compile_program(model: FlatModel) -> Program:
    """Compile every command of *model* and group the commands into choice groups.

    :raises ArgumentError: for a model not flattened (a parsed one, given to a builder).
    """
    names = _names(require_flat(model))
    program = _program(model, names, lambda m, c: _compile_command(m, c, names))
    names.cache.grids.clear()  # only the tables needed them
    return program


def with_probabilities(program: Program, model: FlatModel) -> Program:
    """*program* with the update probabilities of *model*, guards and assignments kept.

    *model* must have the commands *program* was compiled from, in the same
    order, up to their probabilities (as the models of one ``reuse.structure`` key do):
    only the probabilities are compiled again.
    """
    names = _names(model)
    old = iter(c for g in program.groups for part in g.parts for c in part)
    return _program(model, names, lambda m, c: _new_probabilities(next(old), c, names))


def _names(model: FlatModel) -> _Names:
    return _Names(model.variable_names, {v.name: (v.low, v.high) for v in model.variables})


def _program(
    model: FlatModel, names: _Names, compile_one: Callable[[FlatModule, Command], CompiledCommand]
) -> Program:
    """The choice groups of *model*, each command compiled by *compile_one*."""

    def commands(module: FlatModule, action: str | None) -> tuple[CompiledCommand, ...]:
        return tuple(compile_one(module, c) for c in module.commands if c.action == action)

    def group(action: str | None, parts: tuple[tuple[CompiledCommand, ...], ...]
              ) -> ChoiceGroup:
        indexes = tuple(equality_index([c.command.guard for c in part], names.names,
                                       names.ranges) for part in parts)
        return ChoiceGroup(action, parts, indexes if any(indexes) else ())

    groups = [
        group(None, (commands(m, None),))
        for m in model.modules
        if any(c.action is None for c in m.commands)
    ]
    for action in _actions(model):
        groups.append(group(action, tuple(commands(m, action) for m in model.modules
                                          if action in m.alphabet)))
    return Program(
        variable_names=names.names,
        lows=tuple(v.low for v in model.variables),
        highs=tuple(v.high for v in model.variables),
        groups=tuple(groups),
    )


def _actions(model: FlatModel) -> list[str]:
    """Action labels in order of first appearance (module order, then command order)."""
    seen: dict[str, None] = {}
    for module in model.modules:
        for action in sorted(module.alphabet):
            seen.setdefault(action, None)
        for command in module.commands:
            if command.action is not None:
                seen.setdefault(command.action, None)
    return list(seen)


@dataclass(frozen=True, slots=True)
class _Names:
    names: tuple[str, ...]
    ranges: dict[str, tuple[int, int]]
    cache: CompileCache = field(default_factory=CompileCache)

    def compile(self, expr: Expr) -> CompiledExpr:
        """Compile over the state vector, tabulating small sub-domains (shared cache)."""
        return compile_expr(expr, self.names, ranges=self.ranges, cache=self.cache)


def _compile_command(module: FlatModule, command: Command, names: _Names) -> CompiledCommand:
    updates = tuple(_compile_update(u, names) for u in command.updates)
    return CompiledCommand(
        module=module.name,
        command=command,
        guard=names.compile(command.guard),
        updates=updates,
        always=constant_value(command.guard, names.names, names.cache) is True,
        constant_total=_constant_total(updates),
    )


def _new_probabilities(old: CompiledCommand, command: Command, names: _Names) -> CompiledCommand:
    updates = tuple(
        replace(u, probability=names.compile(new.probability),
                constant_probability=_constant(new.probability, names), span=new.span)
        for u, new in zip(old.updates, command.updates, strict=True)
    )
    return replace(old, command=command, updates=updates, constant_total=_constant_total(updates))


def _constant_total(updates: tuple[CompiledUpdate, ...]) -> float | None:
    """The sum of the update probabilities if they are all constants, else None."""
    constants = [u.constant_probability for u in updates]
    if any(v is None for v in constants):
        return None
    return float(sum(v for v in constants if v is not None))


def _constant(expr: Expr, names: _Names) -> float | None:
    value = constant_value(expr, names.names, names.cache)
    return None if value is None else float(value)


def _compile_update(update: Update, names: _Names) -> CompiledUpdate:
    columns = {name: i for i, name in enumerate(names.names)}
    bounds = {n: (float(lo), float(hi)) for n, (lo, hi) in names.ranges.items()}
    assignments, unchecked, constants = [], set(), []
    for a in update.assignments:
        if a.variable not in columns:
            raise PrismSemanticError(f"assignment to unknown variable '{a.variable}'", a.span)
        if isinstance(a.expr, Ident) and a.expr.name == a.variable:
            continue  # (x'=x) leaves the copied source value as it is
        assignments.append((columns[a.variable], names.compile(a.expr)))
        value = constant_value(a.expr, names.names, names.cache)
        constants.append(int(value) if isinstance(value, int) else None)  # bool is an int
        low, high = names.ranges[a.variable]
        interval = value_bounds(a.expr, bounds)
        if interval is not None and low <= interval[0] and interval[1] <= high:
            unchecked.add(columns[a.variable])
    return CompiledUpdate(
        probability=names.compile(update.probability),
        assignments=tuple(assignments),
        span=update.span,
        constant_probability=_constant(update.probability, names),
        unchecked=frozenset(unchecked),
        constants=tuple(constants),
    )
