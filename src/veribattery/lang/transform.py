"""Grammar rules → AST nodes: one method per rule of ``prism.lark``, a span on every node.

Plain Python (no lark): :mod:`veribattery.lang.parser` wraps :class:`ToNodes` as a
lark transformer, and the fast parser (:mod:`veribattery.lang.fastparse`) calls the
same methods (and the expression builders below) with the same children, so both
paths build identical nodes.

The grammar accepts more of PRISM's property language than we check (filters,
steady state, LTL-style path formulas, time intervals), so that whole PRISM
properties files parse. Such constructs become an ``Unsupported`` marker that
propagates up to the enclosing property, which is then kept with its reason;
:func:`veribattery.lang.properties.resolve_property` reports it if it is used.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

from veribattery.errors import PrismSemanticError, PrismSyntaxError, Span
from veribattery.lang.nodes import (
    Assignment,
    Binary,
    BinaryOp,
    BoolLit,
    Call,
    Command,
    ConstDecl,
    DoubleLit,
    Expr,
    FormulaDecl,
    FunctionName,
    Ident,
    IntLit,
    Ite,
    LabelDecl,
    LabelRef,
    Model,
    ModelType,
    Module,
    PropertiesFile,
    Property,
    RenamedModule,
    RewardItem,
    RewardStruct,
    Unary,
    UnaryOp,
    Update,
    ValueType,
    VarDecl,
)
from veribattery.lang.ops import OperatorError, int_literal
from veribattery.lang.path_values import (
    LTL_CONNECTIVES,
    Unsupported,
    Value,
    first_bad,
    is_path,
    ltl_connective,
)
from veribattery.lang.property_rules import Meta, PropertyRules

_DTMC_TYPES = frozenset({"dtmc", "probabilistic"})
_MDP_TYPES = frozenset({"mdp", "nondeterministic"})
#: The other model types of PRISM and PRISM-games, refused by name: the grammar reads
#: ctmc, stochastic, pta, ctmdp and smg (:func:`_model_type` refuses them), and for the
#: rest, which do not parse, the parser's error path names the type.
OTHER_MODEL_TYPES = frozenset({"ctmc", "stochastic", "ctmdp", "pta", "pomdp", "popta", "lts",
                               "smg", "csg", "tsg", "tptg"})


def unsupported_type(name: str) -> str:
    """Why a model of type *name* is refused."""
    return f"only DTMC and MDP models are supported, not '{name}'"


@dataclass(frozen=True, slots=True)
class _Global:
    decl: VarDecl


@dataclass(frozen=True, slots=True)
class _Init:
    expr: Expr
    span: Span


@dataclass(frozen=True, slots=True)
class _ModelType:
    name: str
    span: Span


def _unquote(token: str) -> str:
    return str(token)[1:-1]


def binary(left: Any, op: str, right: Any, span: Span) -> Value:
    """``left op right`` (``^`` is ``pow``); an unsupported operand makes it unsupported,
    a path formula operand of a connective makes it LTL."""
    if op in LTL_CONNECTIVES and (is_path(left) or is_path(right)):
        return ltl_connective(op, [left, right], span)
    bad = first_bad([left, right])
    if bad is not None:
        return bad
    if op == "^":
        return Call("pow", (left, right), span)
    return Binary(cast(BinaryOp, op), left, right, span)


def unary(op: str, operand: Any, span: Span) -> Value:
    """``!a`` or ``-a``."""
    if op == "!" and is_path(operand):
        return ltl_connective(op, [operand], span)
    bad = first_bad([operand])
    return bad or Unary(cast(UnaryOp, op), operand, span)


def ite(cond: Any, then: Any, otherwise: Any, span: Span) -> Value:
    """``cond ? then : otherwise``."""
    bad = first_bad([cond, then, otherwise])
    return bad or Ite(cond, then, otherwise, span)


def call(name: str, args: list[Any], span: Span) -> Value:
    """A built-in function call."""
    bad = first_bad(args)
    if bad is not None:
        return bad
    return Call(cast(FunctionName, name), tuple(args), span)


class ToNodes(PropertyRules):
    """Build :mod:`veribattery.lang.nodes` objects, rule by rule, for ``prism.lark``.

    Tokens are ``str`` subclasses (lark's ``Token`` or the fast parser's word), so a
    plain ``str`` child is a value a rule returned (``const_type``), never a token.
    """

    def __init__(self, text: str, source: str) -> None:
        super().__init__()
        self._text = text
        self._source = source

    # -------------------------------------------------------------- helpers

    def _model_expr(self, value: Value) -> Expr:
        """An expression in a model file: temporal and unsupported constructs are errors."""
        bad = first_bad([value])
        if bad is not None:
            raise PrismSyntaxError(bad.reason, bad.span)
        return cast(Expr, value)

    # ---------------------------------------------------------- expressions

    def int_lit(self, meta: Meta, children: list[str]) -> Expr:
        try:
            return IntLit(int_literal(children[0]), self._span(meta))
        except OperatorError as exc:
            raise PrismSyntaxError(exc.message, self._span(meta)) from None

    def double_lit(self, meta: Meta, children: list[str]) -> Expr:
        return DoubleLit(float(children[0]), str(children[0]), self._span(meta))

    def true_lit(self, meta: Meta, children: list[str]) -> Expr:
        return BoolLit(True, self._span(meta))

    def false_lit(self, meta: Meta, children: list[str]) -> Expr:
        return BoolLit(False, self._span(meta))

    def ident(self, meta: Meta, children: list[str]) -> Expr:
        return Ident(str(children[0]), self._span(meta))

    def label_ref(self, meta: Meta, children: list[str]) -> Expr:
        return LabelRef(_unquote(children[0]), self._span(meta))

    def binop(self, meta: Meta, children: list[Any]) -> Value:
        left, op, right = children
        return binary(left, str(op), right, self._span(meta))

    def unop(self, meta: Meta, children: list[Any]) -> Value:
        op, operand = children
        return unary(str(op), operand, self._span(meta))

    def ite(self, meta: Meta, children: list[Any]) -> Value:
        return ite(children[0], children[1], children[2], self._span(meta))

    def func_name(self, meta: Meta, children: list[str]) -> str:
        return children[0]

    def call(self, meta: Meta, children: list[Any]) -> Value:
        return call(str(children[0]), children[1:], self._span(meta))

    # ------------------------------------------------------------ model items

    def model_type(self, meta: Meta, children: list[str]) -> _ModelType:
        return _ModelType(str(children[0]), self._span(meta))

    def const_type(self, meta: Meta, children: list[str]) -> ValueType:
        name = str(children[0])
        # "rate" and "prob" are PRISM's old spellings of double.
        return "double" if name in ("rate", "prob") else cast(ValueType, name)

    def const_decl(self, meta: Meta, children: list[Any]) -> ConstDecl:
        kind: ValueType = (
            children.pop(0)
            if type(children[0]) is str  # const_type's value; a token is a str subclass
            else "int"
        )
        name, value = children[0], children[1] if len(children) > 1 else None
        expr = None if value is None else self._model_expr(value)
        return ConstDecl(str(name), kind, expr, self._span(meta))

    def formula_decl(self, meta: Meta, children: list[Any]) -> FormulaDecl:
        return FormulaDecl(str(children[0]), self._model_expr(children[1]), self._span(meta))

    def label_decl(self, meta: Meta, children: list[Any]) -> LabelDecl:
        return LabelDecl(_unquote(children[0]), self._model_expr(children[1]), self._span(meta))

    def var_init(self, meta: Meta, children: list[Any]) -> Expr:
        return self._model_expr(children[0])

    def int_var(self, meta: Meta, children: list[Any]) -> VarDecl:
        name, low, high, *init = children
        low, high = self._model_expr(low), self._model_expr(high)
        return VarDecl(str(name), "int", low, high, init[0] if init else None, self._span(meta))

    def bool_var(self, meta: Meta, children: list[Any]) -> VarDecl:
        name, *init = children
        return VarDecl(str(name), "bool", None, None, init[0] if init else None, self._span(meta))

    def global_decl(self, meta: Meta, children: list[Any]) -> _Global:
        return _Global(children[0])

    def assignment(self, meta: Meta, children: list[Any]) -> Assignment:
        return Assignment(str(children[0]), self._model_expr(children[1]), self._span(meta))

    def assignments(self, meta: Meta, children: list[Any]) -> tuple[Assignment, ...]:
        return tuple(children)

    def true_update(self, meta: Meta, children: list[Any]) -> tuple[Assignment, ...]:
        return ()

    def prob_update(self, meta: Meta, children: list[Any]) -> Update:
        prob = self._model_expr(children[0])
        return Update(prob, children[1], self._span(meta))

    def plain_update(self, meta: Meta, children: list[Any]) -> tuple[Update, ...]:
        # A single update without a probability is taken with probability 1.
        return (Update(IntLit(1, self._span(meta)), children[0], self._span(meta)),)

    def updates(self, meta: Meta, children: list[Any]) -> tuple[Any, ...]:
        return tuple(children)

    def command(self, meta: Meta, children: list[Any]) -> Command:
        action = str(children.pop(0)) if isinstance(children[0], str) else None
        guard = self._model_expr(children[0])
        return Command(action, guard, children[1], self._span(meta))

    def module(self, meta: Meta, children: list[Any]) -> Module:
        name, *body = children
        variables = tuple(b for b in body if isinstance(b, VarDecl))
        commands = tuple(b for b in body if isinstance(b, Command))
        return Module(str(name), variables, commands, self._span(meta))

    def rename(self, meta: Meta, children: list[str]) -> tuple[str, str]:
        return str(children[0]), str(children[1])

    def renamed_module(self, meta: Meta, children: list[Any]) -> RenamedModule:
        name, base, *renames = children
        return RenamedModule(str(name), str(base), tuple(renames), self._span(meta))

    def transition_reward(self, meta: Meta, children: list[Any]) -> RewardItem:
        action = str(children.pop(0)) if isinstance(children[0], str) else None
        guard, value = self._model_expr(children[0]), self._model_expr(children[1])
        return RewardItem(True, action, guard, value, self._span(meta))

    def state_reward(self, meta: Meta, children: list[Any]) -> RewardItem:
        guard, value = self._model_expr(children[0]), self._model_expr(children[1])
        return RewardItem(False, None, guard, value, self._span(meta))

    def rewards(self, meta: Meta, children: list[Any]) -> RewardStruct:
        name = _unquote(children.pop(0)) if children and isinstance(children[0], str) else None
        return RewardStruct(name, tuple(children), self._span(meta))

    def init_block(self, meta: Meta, children: list[Any]) -> _Init:
        return _Init(self._model_expr(children[0]), self._span(meta))

    def start_model(self, meta: Meta, children: list[Any]) -> Model:
        return _assemble_model(children, self._source)

    # ----------------------------------------------------------- properties

    def property(self, meta: Meta, children: list[Any]) -> Property:
        name = _unquote(children[0]) if len(children) == 2 else None
        start = children[0].end_pos if name is not None else meta.start_pos
        text = self._text[start : meta.end_pos].strip()
        text = text[1:].strip() if name is not None else text
        formula = children[-1]
        span = self._span(meta)
        if is_path(formula):
            formula = Unsupported("a path formula needs a P or R operator around it", span)
        if isinstance(formula, Unsupported):
            return Property(BoolLit(False, span), name, text, span, unsupported=formula.reason)
        return Property(formula, name, text, span)

    def start_props(self, meta: Meta, children: list[Any]) -> PropertiesFile:
        labels = tuple(c for c in children if isinstance(c, LabelDecl))
        properties = tuple(c for c in children if isinstance(c, Property))
        _check_quoted_names(labels, properties)
        return PropertiesFile(
            tuple(c for c in children if isinstance(c, ConstDecl)), labels, properties,
            self._source,
        )

    def start_property(self, meta: Meta, children: list[Any]) -> Property:
        return cast(Property, children[0])


def _check_quoted_names(labels: tuple[LabelDecl, ...], properties: tuple[Property, ...]
                        ) -> None:
    """A property name is used once, and not as a label of the file (PRISM refuses both:
    ``"name"`` would read either)."""
    seen = {label.name: ("label", label.span) for label in labels}
    for prop in properties:
        if prop.name is None:
            continue
        if prop.name in seen:
            what, span = seen[prop.name]
            raise PrismSemanticError(f'duplicate name "{prop.name}": a property here and a '
                                     f"{what} at {span}", prop.span)
        seen[prop.name] = ("property", prop.span)


def _model_type(items: list[Any], source: str) -> ModelType:
    """DTMCs and MDPs are supported; PRISM assumes mdp when no type is given."""
    types = [item for item in items if isinstance(item, _ModelType)]
    if not types:
        return "mdp"
    if len(types) > 1:
        raise PrismSemanticError("the model type is given more than once", types[1].span)
    if types[0].name in _DTMC_TYPES:
        return "dtmc"
    if types[0].name in _MDP_TYPES:
        return "mdp"
    raise PrismSemanticError(unsupported_type(types[0].name), types[0].span)


def _assemble_model(items: list[Any], source: str) -> Model:
    model_type = _model_type(items, source)
    inits = [item for item in items if isinstance(item, _Init)]
    if len(inits) > 1:
        raise PrismSemanticError("more than one init ... endinit block", inits[1].span)
    return Model(
        model_type=model_type,
        constants=tuple(i for i in items if isinstance(i, ConstDecl)),
        formulas=tuple(i for i in items if isinstance(i, FormulaDecl)),
        labels=tuple(i for i in items if isinstance(i, LabelDecl)),
        globals=tuple(i.decl for i in items if isinstance(i, _Global)),
        modules=tuple(i for i in items if isinstance(i, Module | RenamedModule)),
        rewards=tuple(i for i in items if isinstance(i, RewardStruct)),
        init=inits[0].expr if inits else None,
        source=source,
    )
