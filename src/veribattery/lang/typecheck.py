"""Static types of expressions (int, double, bool), with PRISM's rules.

Numbers mix freely (int + double is double, ``/`` is always double); booleans
only meet booleans. Errors name the operator and the operand types.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, cast

from veribattery.errors import PrismSemanticError, Span
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    Conditional,
    ConditionalReach,
    CosafeReach,
    Cumulative,
    DoubleLit,
    Eventually,
    Expr,
    Filter,
    Globally,
    Ident,
    Instantaneous,
    IntLit,
    Ite,
    LabelRef,
    LtlBinary,
    LtlNot,
    LtlPath,
    LtlTemporal,
    Multi,
    Next,
    ProbOp,
    Quantified,
    Reach,
    ReachNext,
    ReachUntil,
    Release,
    RewardBounded,
    RewardOp,
    SteadyOp,
    TimeBound,
    TimeInterval,
    Unary,
    Until,
    ValueType,
    WeakUntil,
)
from veribattery.lang.ops import BINARY, FUNCTIONS, conditional_type


def _numeric(kind: ValueType) -> bool:
    return kind in ("int", "double")


class TypeEnv:
    """Names in scope with their types; *in_property* allows labels and P/R operators.

    With *memo*, the type of each checked compound expression is remembered per node
    object, so that a shared sub-tree (an inlined formula) is checked once; *types*
    must then not change.
    """

    def __init__(
        self, types: Mapping[str, ValueType], *, in_property: bool = False, memo: bool = False
    ) -> None:
        self.types = types
        self.in_property = in_property
        self.memo: dict[int, tuple[Expr, ValueType]] | None = {} if memo else None

    def lookup(self, ident: Ident) -> ValueType:
        if ident.name not in self.types:
            raise PrismSemanticError(f"unknown identifier '{ident.name}'", ident.span)
        return self.types[ident.name]


def type_of(expr: Expr, env: TypeEnv) -> ValueType:
    """The type of *expr*; raises :class:`PrismSemanticError` on a type error."""
    cls = type(expr)
    if cls is Ident:
        return env.lookup(cast(Ident, expr))
    if cls is IntLit:
        return "int"
    if cls is DoubleLit:
        return "double"
    if cls is BoolLit:
        return "bool"
    memo = env.memo
    if memo is not None:
        hit = memo.get(id(expr))
        if hit is not None:
            return hit[1]
    return _compound(expr, env)


# Steps of the checker's own stack: a model's expressions may nest thousands deep.
_VISIT, _FINISH, _REQUIRE_BOOL, _REQUIRE_NUMBER = 0, 1, 2, 3
_Step = tuple[int, Any, str]


def _compound(root: Expr, env: TypeEnv) -> ValueType:
    """The type of a compound *root*, children first, without recursion.

    Checks run in the order of the recursive definition they replace (a condition
    before its branches, each argument before the next), so that of two errors
    the same one is reported.
    """
    kinds: dict[int, ValueType] = {}
    todo: list[_Step] = [(_VISIT, root, "")]
    while todo:
        step, node, what = todo.pop()
        if step == _VISIT:
            kind = _known(node, env, kinds)
            if kind is not None:
                kinds[id(node)] = kind
                continue
            todo.append((_FINISH, node, ""))
            todo.extend(reversed(_plan(node)))
        elif step == _FINISH:
            kind = _finish(node, kinds)
            kinds[id(node)] = kind
            if env.memo is not None:
                env.memo[id(node)] = (node, kind)
        else:
            wanted = "bool" if step == _REQUIRE_BOOL else "numeric"
            _require(kinds[id(node)], node, wanted, what)
    return kinds[id(root)]


def _known(node: Expr, env: TypeEnv, kinds: Mapping[int, ValueType]) -> ValueType | None:
    """The type of a leaf, of a node already typed, or of a property operator; else None."""
    cls = type(node)
    if cls is Ident or cls is IntLit or cls is DoubleLit or cls is BoolLit:
        return type_of(node, env)
    found = kinds.get(id(node))
    if found is not None:
        return found
    if env.memo is not None:
        hit = env.memo.get(id(node))
        if hit is not None:
            return hit[1]
    if cls is Binary or cls is Ite or cls is Unary:
        return None
    if cls is Call:
        _check_arity(cast(Call, node))
        return None
    return _property_type(node, env)


def _plan(node: Expr) -> list[_Step]:
    """What to do for *node*'s operands, in order (before it is finished)."""
    if isinstance(node, Binary):
        return [(_VISIT, node.left, ""), (_VISIT, node.right, "")]
    if isinstance(node, Unary):
        return [(_VISIT, node.operand, "")]
    if isinstance(node, Ite):
        return [
            (_VISIT, node.cond, ""),
            (_REQUIRE_BOOL, node.cond, "the condition of '? :'"),
            (_VISIT, node.then, ""),
            (_VISIT, node.otherwise, ""),
        ]
    call = cast(Call, node)
    steps: list[_Step] = []
    for arg in call.args:
        steps += [(_VISIT, arg, ""), (_REQUIRE_NUMBER, arg, f"an argument of {call.func}")]
    return steps


def _finish(node: Expr, kinds: Mapping[int, ValueType]) -> ValueType:
    """The type of *node* from its operands' types."""
    if isinstance(node, Binary):
        return _binary(node, kinds[id(node.left)], kinds[id(node.right)])
    if isinstance(node, Unary):
        return _unary(node, kinds[id(node.operand)])
    if isinstance(node, Ite):
        return _ite(node, kinds[id(node.then)], kinds[id(node.otherwise)])
    call = cast(Call, node)
    return _call(call, [kinds[id(a)] for a in call.args])


def expect(expr: Expr, env: TypeEnv, wanted: str, what: str) -> ValueType:
    """Check that *expr* is ``bool`` or ``numeric`` (*wanted*); *what* names the context."""
    kind = type_of(expr, env)
    _require(kind, expr, wanted, what)
    return kind


def _require(kind: ValueType, expr: Expr, wanted: str, what: str) -> None:
    """Raise unless *kind* is ``bool`` or ``numeric``, as *wanted*."""
    ok = kind == "bool" if wanted == "bool" else _numeric(kind)
    if not ok:
        article = "a bool" if wanted == "bool" else "a number"
        raise PrismSemanticError(f"type error: {what} must be {article}, not {kind}", expr.span)


def _unary(expr: Unary, kind: ValueType) -> ValueType:
    if expr.op == "!" and kind != "bool":
        raise PrismSemanticError(f"type error: '!' needs a bool, not {kind}", expr.span)
    if expr.op == "-" and not _numeric(kind):
        raise PrismSemanticError(f"type error: unary '-' needs a number, not {kind}", expr.span)
    return kind


def _binary(expr: Binary, left: ValueType, right: ValueType) -> ValueType:
    kind = BINARY[expr.op].result((left, right))
    if kind is None:
        raise PrismSemanticError(
            f"type error: operator '{expr.op}' cannot be applied to {left} and {right}",
            expr.span,
        )
    return kind


def _ite(expr: Ite, then: ValueType, otherwise: ValueType) -> ValueType:
    kind = conditional_type(then, otherwise)
    if kind is None:
        raise PrismSemanticError(
            f"type error: the branches of '? :' are {then} and {otherwise}", expr.span
        )
    return kind


def _check_arity(expr: Call) -> None:
    function = FUNCTIONS[expr.func]
    if not function.accepts(len(expr.args)):
        low, high = function.arity
        count = f"{low}" if low == high else f"at least {low}"
        raise PrismSemanticError(
            f"{expr.func}(...) takes {count} arguments, not {len(expr.args)}", expr.span
        )


def _call(expr: Call, kinds: list[ValueType]) -> ValueType:
    kind = FUNCTIONS[expr.func].result(kinds)
    if kind is None:  # the arguments are numbers (checked before): mod wants ints
        for arg, arg_kind in zip(expr.args, kinds, strict=True):
            if arg_kind != "int":
                raise PrismSemanticError(
                    f"type error: {expr.func}(...) needs int arguments", arg.span)
    assert kind is not None
    return kind


# ----------------------------------------------------------------- properties


def _not_in_model(expr: Expr, env: TypeEnv, what: str) -> None:
    if not env.in_property:
        raise PrismSemanticError(f"{what} can only be used in properties", _span(expr))


def _span(expr: object) -> Span | None:
    span = getattr(expr, "span", None)
    return span if isinstance(span, Span) else None


def _property_type(expr: Expr, env: TypeEnv) -> ValueType:
    if isinstance(expr, LabelRef):
        _not_in_model(expr, env, f'the label "{expr.name}"')
        return "bool"
    if isinstance(expr, ProbOp):
        _not_in_model(expr, env, "the P operator")
        _check_query_bound(expr.bound, env)
        _check_path(expr.path, env)
        return "double" if expr.op == "=?" else "bool"
    if isinstance(expr, RewardOp):
        _not_in_model(expr, env, "the R operator")
        _check_query_bound(expr.bound, env)
        _check_reward_path(expr.path, env)
        return "double" if expr.op == "=?" else "bool"
    return _extended_type(expr, env)


def _extended_type(expr: Expr, env: TypeEnv) -> ValueType:
    if isinstance(expr, SteadyOp):
        _not_in_model(expr, env, "the S operator")
        _check_query_bound(expr.bound, env)
        expect(expr.operand, env, "bool", "the operand of S")
        return "double" if expr.op == "=?" else "bool"
    if isinstance(expr, Quantified):
        _not_in_model(expr, env, f"the CTL operator {expr.quantifier}")
        _check_path(expr.path, env)
        return "bool"
    if isinstance(expr, Filter):
        _not_in_model(expr, env, "filter(...)")
        return _filter_type(expr, env)
    if isinstance(expr, Multi):
        _not_in_model(expr, env, "multi(...)")
        return _multi_type(expr, env)
    raise PrismSemanticError(f"unexpected expression {type(expr).__name__}", _span(expr))


def _filter_type(expr: Filter, env: TypeEnv) -> ValueType:
    if expr.states is not None:
        expect(expr.states, env, "bool", "the states of a filter")
    if expr.op in ("forall", "exists", "count", "argmin", "argmax"):
        wanted = "bool" if expr.op in ("forall", "exists", "count") else "numeric"
        expect(expr.operand, env, wanted, f"the property of filter({expr.op}, ...)")
        return "int" if expr.op == "count" else "bool"
    kind = type_of(expr.operand, env)
    if expr.op in ("min", "max", "sum", "avg", "range") and not _numeric(kind):
        raise PrismSemanticError(
            f"type error: filter({expr.op}, ...) needs a numeric property, not {kind}", expr.span)
    return "double" if expr.op == "avg" else kind


def _multi_type(expr: Multi, env: TypeEnv) -> ValueType:
    """Every objective a P or R operator; a boolean unless one of them asks ``=?``."""
    for objective in expr.objectives:
        if not isinstance(objective, ProbOp | RewardOp):
            raise PrismSemanticError("the objectives of multi(...) must be P or R operators",
                                     _span(objective))
        _property_type(objective, env)
    queried = any(o.op == "=?" for o in expr.objectives if isinstance(o, ProbOp | RewardOp))
    return "double" if queried else "bool"


def _check_query_bound(bound: Expr | None, env: TypeEnv) -> None:
    if bound is not None:
        expect(bound, env, "numeric", "the bound of a P or R operator")


def check_time(bound: TimeBound | TimeInterval | Expr | None, env: TypeEnv) -> None:
    """A step bound must be an int."""
    if isinstance(bound, TimeInterval):
        check_time(bound.low, env)
        check_time(bound.high, env)
        return
    value = bound.value if isinstance(bound, TimeBound) else bound
    if value is not None and type_of(value, env) != "int":
        raise PrismSemanticError("type error: a step bound must be an int", value.span)


def _check_path(path: object, env: TypeEnv) -> None:
    if isinstance(path, Next):
        expect(path.operand, env, "bool", "the operand of X")
    elif isinstance(path, Eventually | Globally):
        check_time(path.bound, env)
        expect(path.operand, env, "bool", "the operand of F or G")
    elif isinstance(path, Until | WeakUntil | Release):
        check_time(path.bound, env)
        expect(path.left, env, "bool", "the left operand of U, W or R")
        expect(path.right, env, "bool", "the right operand of U, W or R")
    elif isinstance(path, LtlPath):
        _check_ltl(path.formula, env)
    else:
        _check_storm_path(path, env)


def _check_storm_path(path: object, env: TypeEnv) -> None:
    """Storm's reward-bounded ``F{"r"}<=T`` / ``U{"r"}<=T`` and conditional ``||``."""
    if isinstance(path, RewardBounded):
        expect(path.bound.value, env, "numeric", "a reward bound")
        expect(path.left, env, "bool", "the left operand of U")
        expect(path.right, env, "bool", "the operand of F or U")
    elif isinstance(path, Conditional):
        _check_path(path.path, env)
        expect(path.condition, env, "bool", "the condition after ||")


def _check_ltl(formula: object, env: TypeEnv) -> None:
    """The state formulas an LTL path reads, left to right: booleans."""
    todo = [formula]
    while todo:  # (a stack of its own: an LTL formula may nest deeply)
        node = todo.pop()
        if isinstance(node, LtlNot):
            todo.append(node.operand)
        elif isinstance(node, LtlBinary):
            todo += [node.right, node.left]
        elif isinstance(node, LtlTemporal):
            todo += [node.right] if node.left is None else [node.right, node.left]
        else:
            expect(cast(Expr, node), env, "bool", "an operand of an LTL formula")


def _check_reward_path(path: object, env: TypeEnv) -> None:
    if isinstance(path, Cumulative):
        check_time(path.bound, env)
    elif isinstance(path, Instantaneous):
        check_time(path.time, env)
    elif isinstance(path, Reach | ReachNext):
        expect(path.target, env, "bool", "the target of F or X")
    elif isinstance(path, ReachUntil):
        expect(path.left, env, "bool", "the left operand of U")
        expect(path.right, env, "bool", "the right operand of U")
    elif isinstance(path, ConditionalReach):
        expect(path.target, env, "bool", "the target of F")
        expect(path.condition, env, "bool", "the condition after ||")
    elif isinstance(path, CosafeReach):
        _check_ltl(path.formula, env)
