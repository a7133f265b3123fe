"""Model and property-file nodes: the syntax layer the parser produces and the flat
layer semantic analysis produces for the state-space builder."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal, Protocol, TypeAlias

from veribattery.errors import NO_SPAN, Span
from veribattery.lang.nodes.expr import (
    Value,
    ValueType,
)
from veribattery.lang.nodes.pctl import (
    Expr,
)

__all__ = [
    "Assignment",
    "Command",
    "ConstDecl",
    "FlatModel",
    "FlatModule",
    "FormulaDecl",
    "LabelDecl",
    "Model",
    "ModelType",
    "Module",
    "PropertiesFile",
    "Property",
    "RenamedModule",
    "RewardItem",
    "RewardStruct",
    "Update",
    "VarDecl",
    "Variable",
]

# ---------------------------------------------------------------------------
# Model syntax (what the parser produces)
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class ConstDecl:
    """``const [int|double|bool] name [= value];`` -- *value* None means undefined."""

    name: str
    type: ValueType
    value: Expr | None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class FormulaDecl:
    """``formula name = expr;``."""

    name: str
    expr: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class LabelDecl:
    """``label "name" = expr;``."""

    name: str
    expr: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class VarDecl:
    """``name : [low..high] init e;`` or ``name : bool init e;`` (``global`` if at top level)."""

    name: str
    type: Literal["int", "bool"]
    low: Expr | None
    high: Expr | None
    init: Expr | None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Assignment:
    """``(x' = expr)``."""

    variable: str
    expr: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Update:
    """One probabilistic branch ``p : (x'=..) & (y'=..)``; ``true`` has no assignments."""

    probability: Expr
    assignments: tuple[Assignment, ...]
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Command:
    """``[action] guard -> updates;`` -- *action* None for ``[]``."""

    action: str | None
    guard: Expr
    updates: tuple[Update, ...]
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Module:
    """``module name ... endmodule``."""

    name: str
    variables: tuple[VarDecl, ...]
    commands: tuple[Command, ...]
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class RenamedModule:
    """``module name = base [old=new, ...] endmodule``."""

    name: str
    base: str
    renames: tuple[tuple[str, str], ...]
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class RewardItem:
    """``[action] guard : value;`` (transition reward) or ``guard : value;`` (state reward)."""

    is_transition: bool
    action: str | None
    guard: Expr
    value: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class RewardStruct:
    """``rewards ["name"] ... endrewards`` -- *name* None when unnamed."""

    name: str | None
    items: tuple[RewardItem, ...]
    span: Span = field(default=NO_SPAN, compare=False)


ModelType: TypeAlias = Literal["dtmc", "mdp"]


class _Named(Protocol):
    @property
    def name(self) -> str | None: ...


def _names(declared: Iterable[_Named]) -> tuple[str | None, ...]:
    return tuple(d.name for d in declared)


@dataclass(frozen=True, slots=True, repr=False)  # a short repr: see __repr__
class Model:
    """A whole PRISM model file, declarations in source order per kind."""

    model_type: ModelType
    constants: tuple[ConstDecl, ...]
    formulas: tuple[FormulaDecl, ...]
    labels: tuple[LabelDecl, ...]
    globals: tuple[VarDecl, ...]
    modules: tuple[Module | RenamedModule, ...]
    rewards: tuple[RewardStruct, ...]
    init: Expr | None = None
    source: str = "<string>"

    def __repr__(self) -> str:
        # What a notebook shows of a parsed model: its declarations' names, not every
        # expression with a span on each node (10 kB for the die, megabytes for a mission).
        commands = sum(len(m.commands) for m in self.modules if isinstance(m, Module))
        return (f"Model(model_type={self.model_type!r}, source={self.source!r}, "
                f"constants={_names(self.constants)}, globals={_names(self.globals)}, "
                f"modules={_names(self.modules)}, commands={commands}, "
                f"labels={_names(self.labels)}, rewards={_names(self.rewards)})")


# ---------------------------------------------------------------------------
# Properties files
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, repr=False)  # a short repr: see __repr__
class Property:
    """One property: ``["name":] formula``; *text* is the source text of the formula."""

    formula: Expr
    name: str | None = None
    text: str = ""
    span: Span = field(default=NO_SPAN, compare=False)
    #: Why the property is outside the supported subset (filters, LTL, S ...), or None.
    #: Such properties still parse, so that -prop style indices count them; *formula*
    #: is then a placeholder and resolving the property raises an error.
    unsupported: str | None = None

    def __repr__(self) -> str:
        # Its name and text, as a result shows it: the formula's tree is for the checker.
        return f"Property(name={self.name!r}, text={self.text!r})"


@dataclass(frozen=True, slots=True, repr=False)  # a short repr: see __repr__
class PropertiesFile:
    """A ``.props``/``.pctl`` file: its constants, labels and properties in order."""

    constants: tuple[ConstDecl, ...]
    labels: tuple[LabelDecl, ...]
    properties: tuple[Property, ...]
    source: str = "<string>"

    def __repr__(self) -> str:
        return (f"PropertiesFile(source={self.source!r}, constants={_names(self.constants)}, "
                f"labels={_names(self.labels)}, properties={self.properties!r})")


# ---------------------------------------------------------------------------
# The flat model (what semantic analysis hands to the state-space builder)
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Variable:
    """A state variable with constant integer bounds (bool is 0..1)."""

    name: str
    low: int
    high: int
    init: int
    is_bool: bool
    module: str | None  # None for a global variable
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class FlatModule:
    """A module after renaming: its own variables' names and its commands.

    *alphabet* is the set of action labels its commands use (the modules that
    share an action synchronise on it).
    """

    name: str
    variables: tuple[str, ...]
    commands: tuple[Command, ...]
    alphabet: frozenset[str]
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True, repr=False)  # a short repr: see __repr__
class FlatModel:
    """A checked, closed model: every expression uses only variables and literals.

    Constants are replaced by literals and formulas inlined in commands, labels,
    rewards and *init*. *constants* keeps every constant's value (for properties
    and reporting). *init* is None when each variable's ``init`` defines the
    single initial state.
    """

    variables: tuple[Variable, ...]
    modules: tuple[FlatModule, ...]
    labels: tuple[LabelDecl, ...]
    rewards: tuple[RewardStruct, ...]
    constants: tuple[tuple[str, Value], ...]
    formulas: tuple[FormulaDecl, ...]
    init: Expr | None = None
    source: str = "<string>"
    #: ``"mdp"``: several enabled choices are the scheduler's, not a uniform draw.
    model_type: ModelType = "dtmc"

    @property
    def variable_names(self) -> tuple[str, ...]:
        """Variable names in state-vector order."""
        return tuple(v.name for v in self.variables)

    def __repr__(self) -> str:
        # As Model's: names, the constants' values and the size, not the expressions.
        return (f"FlatModel(model_type={self.model_type!r}, source={self.source!r}, "
                f"constants={dict(self.constants)}, variables={self.variable_names}, "
                f"modules={tuple(m.name for m in self.modules)}, "
                f"commands={sum(len(m.commands) for m in self.modules)}, "
                f"labels={_names(self.labels)}, rewards={_names(self.rewards)})")
