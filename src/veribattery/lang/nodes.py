"""The PRISM-language AST: frozen dataclasses, tuples not lists, a span on every node.

Two layers live here. The *syntax* layer (``Model``, ``Module``, ``Command`` ...) is
what the parser produces, one node per construct in the text. The *flat* layer
(``FlatModel``) is what semantic analysis produces for the state-space builder:
constants replaced by literals, formulas inlined, renamed modules expanded, every
variable given integer bounds and an initial value.

Nothing here imports numpy: the language layer is pure Python.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, TypeAlias

from veribattery.errors import NO_SPAN, Span

# ---------------------------------------------------------------------------
# Expressions (state expressions; P/R operators are expressions too, so that
# they nest inside boolean connectives in property files)
# ---------------------------------------------------------------------------

ValueType: TypeAlias = Literal["int", "double", "bool"]
Value: TypeAlias = int | float | bool


@dataclass(frozen=True, slots=True)
class IntLit:
    """An integer literal."""

    value: int
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class DoubleLit:
    """A double literal; *text* keeps the digits as written (for exact re-printing)."""

    value: float
    text: str = ""
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class BoolLit:
    """``true`` or ``false``."""

    value: bool
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Ident:
    """A name: a variable, constant or formula (resolved by semantic analysis)."""

    name: str
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class LabelRef:
    """A quoted label in a property: ``"success"``, ``"init"``, ``"deadlock"``."""

    name: str
    span: Span = field(default=NO_SPAN, compare=False)


UnaryOp: TypeAlias = Literal["!", "-"]
BinaryOp: TypeAlias = Literal[
    "|", "&", "=>", "<=>", "=", "!=", "<", "<=", ">", ">=", "+", "-", "*", "/"
]


@dataclass(frozen=True, slots=True)
class Unary:
    """``!a`` or ``-a``."""

    op: UnaryOp
    operand: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Binary:
    """``a op b`` for the boolean, relational and arithmetic operators."""

    op: BinaryOp
    left: Expr
    right: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Ite:
    """``cond ? then : otherwise``."""

    cond: Expr
    then: Expr
    otherwise: Expr
    span: Span = field(default=NO_SPAN, compare=False)


FunctionName: TypeAlias = Literal["min", "max", "floor", "ceil", "pow", "mod", "log", "round"]


@dataclass(frozen=True, slots=True)
class Call:
    """A built-in function: ``min max floor ceil pow mod log round`` (``func(f, ...)`` too)."""

    func: FunctionName
    args: tuple[Expr, ...]
    span: Span = field(default=NO_SPAN, compare=False)


# ---------------------------------------------------------------------------
# Property operators (PCTL)
# ---------------------------------------------------------------------------

BoundOp: TypeAlias = Literal["<", "<=", ">", ">="]
#: What each bound operator means, for any ordered values: floats, arrays, rationals.
BOUND_RELATIONS: Mapping[str, Callable[[Any, Any], Any]] = {
    "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge,
}
#: ``"=?"`` asks for the value; the others compare it with a bound.
QueryOp: TypeAlias = Literal["=?", "<", "<=", ">", ">="]


@dataclass(frozen=True, slots=True)
class TimeBound:
    """A step bound on a temporal operator: ``<=k``, ``<k``, ``>=k``, ``>k`` (``=k`` for I)."""

    op: Literal["<", "<=", ">", ">=", "="]
    value: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class TimeInterval:
    """A step interval ``[low,high]`` on a temporal operator (both ends included)."""

    low: Expr
    high: Expr
    span: Span = field(default=NO_SPAN, compare=False)


Bound: TypeAlias = TimeBound | TimeInterval


@dataclass(frozen=True, slots=True)
class Next:
    """``X phi``."""

    operand: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Until:
    """``left U right``, optionally step-bounded."""

    left: Expr
    right: Expr
    bound: Bound | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class WeakUntil:
    """``left W right``: ``left U right`` or ``G left``, optionally step-bounded."""

    left: Expr
    right: Expr
    bound: Bound | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Release:
    """``left R right``: *right* holds up to and including the first *left* state."""

    left: Expr
    right: Expr
    bound: Bound | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Eventually:
    """``F phi``, optionally step-bounded (equivalent to ``true U phi``)."""

    operand: Expr
    bound: Bound | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Globally:
    """``G phi``, optionally step-bounded."""

    operand: Expr
    bound: Bound | None = None
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Cumulative:
    """Reward path ``C<=k``: reward accumulated over the first k steps."""

    bound: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Instantaneous:
    """Reward path ``I=k``: expected state reward at step k."""

    time: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Reach:
    """Reward path ``F phi``: reward accumulated until phi is first reached."""

    target: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Total:
    """Reward path ``C``: the total reward accumulated along the whole path."""

    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class LongRun:
    """Reward path ``S``: the long-run average reward per step."""

    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class ReachUntil:
    """Reward path ``left U right``: reward until *right*, infinite unless it is sure."""

    left: Expr
    right: Expr
    span: Span = field(default=NO_SPAN, compare=False)


# --- Storm's reward-bounded and conditional formulas (checker/reward_bounded.py,
# --- checker/conditional.py).


@dataclass(frozen=True, slots=True)
class RewardBounded:
    """``left U{"r"}<=T right`` (``F{"r"}<=T right`` has *left* ``true``), as in Storm.

    *right* is reached through *left* states with at most T of reward structure
    *reward* accumulated, the step that enters *right* included. *reward* is a name
    or a 0-based index, as in :class:`RewardOp`.
    """

    left: Expr
    right: Expr
    reward: str | int
    bound: TimeBound
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class ReachNext:
    """Reward path ``X phi``: the first step's reward, infinite unless ``X phi`` is sure."""

    target: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Conditional:
    """``P=? [ path || F condition ]``: *path* given that *condition* is reached (Storm)."""

    path: PathFormula
    condition: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class ConditionalReach:
    """Reward path ``F target || F condition``: reward to *target*, given ``F condition``."""

    target: Expr
    condition: Expr
    span: Span = field(default=NO_SPAN, compare=False)


PathFormula: TypeAlias = (
    Next | Until | Eventually | Globally | WeakUntil | Release | RewardBounded | Conditional
)
RewardPath: TypeAlias = (
    Cumulative | Instantaneous | Reach | Total | LongRun | ReachUntil | ReachNext
    | ConditionalReach
)


@dataclass(frozen=True, slots=True)
class ProbOp:
    """``P=? [path]`` or ``P~p [path]``."""

    op: QueryOp
    bound: Expr | None
    path: PathFormula
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class RewardOp:
    """``R{"name"}=? [path]``, ``R=? [path]`` (first structure), or with a bound.

    *reward* is the structure's name, its 0-based index (``R{2}`` is index 1), or
    None for the first structure.
    """

    reward: str | int | None
    op: QueryOp
    bound: Expr | None
    path: RewardPath
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class SteadyOp:
    """``S=? [phi]`` or ``S~p [phi]``: the long-run probability of being in *phi*."""

    op: QueryOp
    bound: Expr | None
    operand: Expr
    span: Span = field(default=NO_SPAN, compare=False)


@dataclass(frozen=True, slots=True)
class Quantified:
    """CTL: ``A [path]`` (on all paths) or ``E [path]`` (on some path)."""

    quantifier: Literal["A", "E"]
    path: PathFormula
    span: Span = field(default=NO_SPAN, compare=False)


FilterOp: TypeAlias = Literal[
    "min", "max", "argmin", "argmax", "count", "sum", "avg", "first", "range",
    "forall", "exists", "print", "printall", "state",
]


@dataclass(frozen=True, slots=True)
class Filter:
    """``filter(op, operand, states)``; *states* None means all states."""

    op: FilterOp
    operand: Expr
    states: Expr | None = None
    span: Span = field(default=NO_SPAN, compare=False)


Expr: TypeAlias = (
    IntLit
    | DoubleLit
    | BoolLit
    | Ident
    | LabelRef
    | Unary
    | Binary
    | Ite
    | Call
    | ProbOp
    | RewardOp
    | SteadyOp
    | Quantified
    | Filter
)

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


ModelType: TypeAlias = Literal["dtmc"]


@dataclass(frozen=True, slots=True)
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


# ---------------------------------------------------------------------------
# Properties files
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
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


@dataclass(frozen=True, slots=True)
class PropertiesFile:
    """A ``.props``/``.pctl`` file: its constants, labels and properties in order."""

    constants: tuple[ConstDecl, ...]
    labels: tuple[LabelDecl, ...]
    properties: tuple[Property, ...]
    source: str = "<string>"


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


@dataclass(frozen=True, slots=True)
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

    @property
    def variable_names(self) -> tuple[str, ...]:
        """Variable names in state-vector order."""
        return tuple(v.name for v in self.variables)
