"""Parse tree → AST nodes: one method per grammar rule, a span on every node.

The grammar accepts more of PRISM's property language than we check (filters,
steady state, LTL-style path formulas, time intervals), so that whole PRISM
properties files parse. Such constructs become an ``_Unsupported`` marker that
propagates up to the enclosing property, which is then kept with its reason;
:func:`veribattery.lang.properties.resolve_property` reports it if it is used.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, TypeAlias, cast

from lark import Token, Transformer, v_args
from lark.tree import Meta

from veribattery.errors import PrismSemanticError, PrismSyntaxError, Span
from veribattery.lang.nodes import (
    Assignment,
    Binary,
    BinaryOp,
    BoolLit,
    Call,
    Command,
    Conditional,
    ConditionalReach,
    ConstDecl,
    Cumulative,
    DoubleLit,
    Eventually,
    Expr,
    FormulaDecl,
    FunctionName,
    Globally,
    Ident,
    Instantaneous,
    IntLit,
    Ite,
    LabelDecl,
    LabelRef,
    Model,
    Module,
    Next,
    PathFormula,
    ProbOp,
    PropertiesFile,
    Property,
    QueryOp,
    Reach,
    RenamedModule,
    RewardBounded,
    RewardItem,
    RewardOp,
    RewardPath,
    RewardStruct,
    TimeBound,
    Unary,
    UnaryOp,
    Until,
    Update,
    ValueType,
    VarDecl,
)

_TimeOp: TypeAlias = Literal["<", "<=", ">", ">=", "="]
_DTMC_TYPES = frozenset({"dtmc", "probabilistic"})
_TEMPORAL_NAMES = {"X": "X (next)", "F": "F (eventually)", "G": "G (globally)", "U": "U (until)",
                   "RB": "a reward-bounded F or U"}


@dataclass(frozen=True, slots=True)
class _Unsupported:
    """A construct that parses but is outside the supported subset."""

    reason: str
    span: Span


@dataclass(frozen=True, slots=True)
class _Temporal:
    """A temporal operator, valid only as the whole path of a P or R operator."""

    op: str
    bound: TimeBound | None
    left: Expr | None
    right: Expr
    span: Span
    #: The reward structure of a reward bound (``F{"r"}<=T``), else None.
    reward: str | int | None = None


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


_Value = Expr | _Temporal | _Unsupported


def _first_bad(values: list[Any]) -> _Unsupported | None:
    """The first unsupported operand; a temporal operand nested in an operator is LTL."""
    for value in values:
        if isinstance(value, _Unsupported):
            return value
        if isinstance(value, _Temporal):
            return _Unsupported(
                f"temporal operator {_TEMPORAL_NAMES[value.op]} inside another operator "
                "(LTL-style path formulas are not supported)",
                value.span,
            )
    return None


def _unquote(token: Token) -> str:
    return str(token)[1:-1]


@v_args(meta=True)
class ToNodes(Transformer[Token, Any]):
    """Build :mod:`veribattery.lang.nodes` objects from a parse tree of ``prism.lark``."""

    def __init__(self, text: str, source: str) -> None:
        super().__init__()
        self._text = text
        self._source = source

    # -------------------------------------------------------------- helpers

    def _span(self, meta: Meta) -> Span:
        return Span(meta.line, meta.column, self._source)

    def _model_expr(self, value: _Value) -> Expr:
        """An expression in a model file: temporal and unsupported constructs are errors."""
        bad = _first_bad([value])
        if bad is not None:
            raise PrismSyntaxError(bad.reason, bad.span)
        return cast(Expr, value)

    # ---------------------------------------------------------- expressions

    def int_lit(self, meta: Meta, children: list[Token]) -> Expr:
        return IntLit(int(children[0]), self._span(meta))

    def double_lit(self, meta: Meta, children: list[Token]) -> Expr:
        return DoubleLit(float(children[0]), str(children[0]), self._span(meta))

    def true_lit(self, meta: Meta, children: list[Token]) -> Expr:
        return BoolLit(True, self._span(meta))

    def false_lit(self, meta: Meta, children: list[Token]) -> Expr:
        return BoolLit(False, self._span(meta))

    def ident(self, meta: Meta, children: list[Token]) -> Expr:
        return Ident(str(children[0]), self._span(meta))

    def label_ref(self, meta: Meta, children: list[Token]) -> Expr:
        return LabelRef(_unquote(children[0]), self._span(meta))

    def binop(self, meta: Meta, children: list[Any]) -> _Value:
        left, op, right = children
        bad = _first_bad([left, right])
        if bad is not None:
            return bad
        return Binary(cast(BinaryOp, str(op)), left, right, self._span(meta))

    def unop(self, meta: Meta, children: list[Any]) -> _Value:
        op, operand = children
        bad = _first_bad([operand])
        return bad or Unary(cast(UnaryOp, str(op)), operand, self._span(meta))

    def ite(self, meta: Meta, children: list[Any]) -> _Value:
        bad = _first_bad(children)
        return bad or Ite(children[0], children[1], children[2], self._span(meta))

    def func_name(self, meta: Meta, children: list[Token]) -> Token:
        return children[0]

    def call(self, meta: Meta, children: list[Any]) -> _Value:
        name, args = str(children[0]), children[1:]
        bad = _first_bad(args)
        if bad is not None:
            return bad
        if name == "round":
            return _Unsupported("function 'round' is not supported", self._span(meta))
        return Call(cast(FunctionName, name), tuple(args), self._span(meta))

    # ------------------------------------------------------ temporal / P / R

    def time_bound(self, meta: Meta, children: list[Any]) -> TimeBound | _Unsupported:
        op, value = children
        bad = _first_bad([value])
        return bad or TimeBound(cast(_TimeOp, str(op)), value, self._span(meta))

    def time_interval(self, meta: Meta, children: list[Any]) -> _Unsupported:
        return _Unsupported("time intervals [a,b] are not supported", self._span(meta))

    def temporal_unop(self, meta: Meta, children: list[Any]) -> _Value:
        op, *rest = children
        bad = _first_bad(rest)
        if bad is not None:
            return bad
        bound = rest[0] if len(rest) == 2 else None
        return _Temporal(str(op), bound, None, rest[-1], self._span(meta))

    def temporal_binop(self, meta: Meta, children: list[Any]) -> _Value:
        left, op, *rest = children
        bad = _first_bad([left, *rest])
        if bad is not None:
            return bad
        bound = rest[0] if len(rest) == 2 else None
        return _Temporal(str(op), bound, left, rest[-1], self._span(meta))

    def query_value(self, meta: Meta, children: list[Any]) -> tuple[QueryOp, Expr | None]:
        return "=?", None

    def query_bound(self, meta: Meta, children: list[Any]) -> Any:
        op, bound = children
        bad = _first_bad([bound])
        return bad or (str(op), bound)

    def state_filter(self, meta: Meta, children: list[Any]) -> _Unsupported:
        return _Unsupported("state filters {...} are not supported", self._span(meta))

    def prob_op(self, meta: Meta, children: list[Any]) -> _Value:
        query, path = children[0], children[1]
        bad = _first_bad(children[2:]) or (query if isinstance(query, _Unsupported) else None)
        if bad is not None:
            return bad
        if isinstance(path, _Unsupported):
            return path
        if not isinstance(path, _Temporal):
            return _Unsupported("P operator needs a path formula (X, F, G or U)", self._span(meta))
        formula = _path_formula(path)
        if isinstance(formula, _Unsupported):
            return formula
        return ProbOp(query[0], query[1], formula, self._span(meta))

    def reward_by_name(self, meta: Meta, children: list[Token]) -> str:
        return _unquote(children[0])

    def reward_by_index(self, meta: Meta, children: list[Token]) -> int:
        # R{2} is the second structure; nodes store 0-based indices.
        return int(children[0]) - 1

    def cumulative(self, meta: Meta, children: list[Any]) -> RewardPath | _Unsupported:
        bound = children[0] if children else None
        if isinstance(bound, _Unsupported):
            return bound
        if bound is None or bound.op != "<=":
            return _Unsupported("only C<=k is supported for cumulative rewards", self._span(meta))
        return Cumulative(bound.value, self._span(meta))

    def instantaneous(self, meta: Meta, children: list[Any]) -> RewardPath | _Unsupported:
        bound = children[0]
        if isinstance(bound, _Unsupported):
            return bound
        if bound.op != "=":
            return _Unsupported("instantaneous rewards need I=k", self._span(meta))
        return Instantaneous(bound.value, self._span(meta))

    def steady_reward(self, meta: Meta, children: list[Any]) -> _Unsupported:
        return _Unsupported("steady-state rewards (S) are not supported", self._span(meta))

    def reach(self, meta: Meta, children: list[Any]) -> RewardPath | _Unsupported:
        path = children[0]
        if isinstance(path, _Unsupported):
            return path
        if isinstance(path, _Temporal) and path.op == "F" and path.bound is None:
            return Reach(path.right, self._span(meta))
        return _Unsupported("reward paths must be F phi, C<=k or I=k", self._span(meta))

    def reward_op(self, meta: Meta, children: list[Any]) -> _Value:
        reward = children[0] if isinstance(children[0], str | int) else None
        rest = children[1:] if isinstance(children[0], str | int) else children
        query, path = rest[0], rest[1]
        bad = _first_bad(rest[2:])
        for item in (bad, query, path):
            if isinstance(item, _Unsupported):
                return item
        return RewardOp(reward, query[0], query[1], path, self._span(meta))

    # ------------------------- Storm's reward-bounded and conditional formulas

    def reward_bounded_unop(self, meta: Meta, children: list[Any]) -> _Value:
        _op, reward, bound, right = children
        return _reward_bounded(BoolLit(True, self._span(meta)), right, reward, bound,
                               self._span(meta))

    def reward_bounded_binop(self, meta: Meta, children: list[Any]) -> _Value:
        left, _op, reward, bound, right = children
        return _reward_bounded(left, right, reward, bound, self._span(meta))

    def conditional_prob_op(self, meta: Meta, children: list[Any]) -> _Value:
        query, path, _cond, condition = children[:4]
        bad = _first_bad(children[4:]) or (query if isinstance(query, _Unsupported) else None)
        objective: PathFormula | _Unsupported
        if bad is not None or isinstance(path, _Unsupported):
            objective = bad or path
        elif not isinstance(path, _Temporal):
            objective = _Unsupported("P operator needs a path formula before ||",
                                     self._span(meta))
        else:
            objective = _path_formula(path)
        target = _condition_target(condition)
        if isinstance(objective, _Unsupported):
            return objective
        if isinstance(target, _Unsupported):
            return target
        conditional = Conditional(objective, target, self._span(meta))
        return ProbOp(query[0], query[1], conditional, self._span(meta))

    def conditional_reach(self, meta: Meta, children: list[Any]) -> RewardPath | _Unsupported:
        path, _cond, condition = children
        reach = self.reach(meta, [path])
        target = _condition_target(condition)
        if isinstance(reach, _Unsupported):
            return reach
        if not isinstance(reach, Reach):
            return _Unsupported("a conditional reward path must be F phi || F psi",
                                self._span(meta))
        if isinstance(target, _Unsupported):
            return target
        return ConditionalReach(reach.target, target, self._span(meta))

    def steady_op(self, meta: Meta, children: list[Any]) -> _Unsupported:
        return _Unsupported("the steady-state operator S is not supported", self._span(meta))

    def filter(self, meta: Meta, children: list[Any]) -> _Unsupported:
        return _Unsupported("filter(...) is not supported", self._span(meta))

    # ------------------------------------------------------------ model items

    def model_type(self, meta: Meta, children: list[Token]) -> _ModelType:
        return _ModelType(str(children[0]), self._span(meta))

    def const_type(self, meta: Meta, children: list[Token]) -> ValueType:
        name = str(children[0])
        # "rate" and "prob" are PRISM's old spellings of double.
        return "double" if name in ("rate", "prob") else cast(ValueType, name)

    def const_decl(self, meta: Meta, children: list[Any]) -> ConstDecl:
        kind: ValueType = (
            children.pop(0)
            if isinstance(children[0], str) and not isinstance(children[0], Token)
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
        action = str(children.pop(0)) if isinstance(children[0], Token) else None
        guard = self._model_expr(children[0])
        return Command(action, guard, children[1], self._span(meta))

    def module(self, meta: Meta, children: list[Any]) -> Module:
        name, *body = children
        variables = tuple(b for b in body if isinstance(b, VarDecl))
        commands = tuple(b for b in body if isinstance(b, Command))
        return Module(str(name), variables, commands, self._span(meta))

    def rename(self, meta: Meta, children: list[Token]) -> tuple[str, str]:
        return str(children[0]), str(children[1])

    def renamed_module(self, meta: Meta, children: list[Any]) -> RenamedModule:
        name, base, *renames = children
        return RenamedModule(str(name), str(base), tuple(renames), self._span(meta))

    def transition_reward(self, meta: Meta, children: list[Any]) -> RewardItem:
        action = str(children.pop(0)) if isinstance(children[0], Token) else None
        guard, value = self._model_expr(children[0]), self._model_expr(children[1])
        return RewardItem(True, action, guard, value, self._span(meta))

    def state_reward(self, meta: Meta, children: list[Any]) -> RewardItem:
        guard, value = self._model_expr(children[0]), self._model_expr(children[1])
        return RewardItem(False, None, guard, value, self._span(meta))

    def rewards(self, meta: Meta, children: list[Any]) -> RewardStruct:
        name = _unquote(children.pop(0)) if children and isinstance(children[0], Token) else None
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
        if isinstance(formula, _Temporal):
            formula = _Unsupported("a path formula needs a P or R operator around it", span)
        if isinstance(formula, _Unsupported):
            return Property(BoolLit(False, span), name, text, span, unsupported=formula.reason)
        return Property(formula, name, text, span)

    def start_props(self, meta: Meta, children: list[Any]) -> PropertiesFile:
        return PropertiesFile(
            tuple(c for c in children if isinstance(c, ConstDecl)),
            tuple(c for c in children if isinstance(c, LabelDecl)),
            tuple(c for c in children if isinstance(c, Property)),
            self._source,
        )

    def start_property(self, meta: Meta, children: list[Any]) -> Property:
        return cast(Property, children[0])


def _path_formula(path: _Temporal) -> PathFormula | _Unsupported:
    """Turn the temporal marker of a P operator into its node."""
    if path.op == "X" and path.bound is not None:
        return _Unsupported("X (next) takes no time bound", path.span)
    if path.bound is not None and path.bound.op == "=":
        return _Unsupported(f"the time bound '=' on {path.op} is not supported", path.span)
    if path.op == "RB":
        return RewardBounded(cast(Expr, path.left), path.right, cast(str | int, path.reward),
                             cast(TimeBound, path.bound), path.span)
    if path.op == "X":
        return Next(path.right, path.span)
    if path.op == "F":
        return Eventually(path.right, path.bound, path.span)
    if path.op == "G":
        return Globally(path.right, path.bound, path.span)
    return Until(cast(Expr, path.left), path.right, path.bound, path.span)


def _reward_bounded(left: Any, right: Any, reward: Any, bound: Any, span: Span) -> _Value:
    """``U{"r"}<=T`` / ``F{"r"}<=T``: only upper bounds (``<=``, ``<``) are supported."""
    bad = _first_bad([left, right, bound])
    if bad is not None:
        return bad
    if bound.op not in ("<=", "<"):
        return _Unsupported(f"the reward bound '{bound.op}' is not supported (use <= or <)",
                            span)
    return _Temporal("RB", bound, left, right, span, reward)


def _condition_target(condition: Any) -> Expr | _Unsupported:
    """The *psi* of a condition ``F psi`` (the only condition Storm accepts)."""
    if isinstance(condition, _Unsupported):
        return condition
    if isinstance(condition, _Temporal) and condition.op == "F" and condition.bound is None:
        return condition.right
    span = condition.span if isinstance(condition, _Temporal) else _node_span(condition)
    return _Unsupported("the condition after || must be F phi (unbounded)", span)


def _node_span(node: Any) -> Span:
    return cast(Span, getattr(node, "span", Span(1, 1)))


def _model_type(items: list[Any], source: str) -> None:
    """Only DTMCs are supported; PRISM assumes mdp when no type is given."""
    types = [item for item in items if isinstance(item, _ModelType)]
    if not types:
        raise PrismSemanticError(
            "no model type given (PRISM then assumes mdp); only DTMC models are supported: "
            "start the file with 'dtmc'",
            Span(1, 1, source),
        )
    if len(types) > 1:
        raise PrismSemanticError("the model type is given more than once", types[1].span)
    if types[0].name not in _DTMC_TYPES:
        raise PrismSemanticError(
            f"only DTMC models are supported, not '{types[0].name}'", types[0].span
        )


def _assemble_model(items: list[Any], source: str) -> Model:
    _model_type(items, source)
    inits = [item for item in items if isinstance(item, _Init)]
    if len(inits) > 1:
        raise PrismSemanticError("more than one init ... endinit block", inits[1].span)
    return Model(
        model_type="dtmc",
        constants=tuple(i for i in items if isinstance(i, ConstDecl)),
        formulas=tuple(i for i in items if isinstance(i, FormulaDecl)),
        labels=tuple(i for i in items if isinstance(i, LabelDecl)),
        globals=tuple(i.decl for i in items if isinstance(i, _Global)),
        modules=tuple(i for i in items if isinstance(i, Module | RenamedModule)),
        rewards=tuple(i for i in items if isinstance(i, RewardStruct)),
        init=inits[0].expr if inits else None,
        source=source,
    )
