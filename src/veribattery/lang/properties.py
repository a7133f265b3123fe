"""Semantic analysis of properties: constants, formulas and labels resolved against a model."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar, cast

from veribattery.errors import PrismSemanticError
from veribattery.lang.constants import ConstantTable, require_constants
from veribattery.lang.evaluate import evaluate
from veribattery.lang.expressions import fold, literal, substitute, walk
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    ConstDecl,
    Cumulative,
    Expr,
    FlatModel,
    Ident,
    Instantaneous,
    LabelRef,
    Model,
    Multi,
    ProbOp,
    PropertiesFile,
    Property,
    RewardBounded,
    RewardOp,
    SteadyOp,
    TimeBound,
    TimeInterval,
    Value,
    ValueType,
)
from veribattery.lang.property_rules import STEPS_REWARD
from veribattery.lang.semantics import BUILTIN_LABELS, check_unique, require_flat
from veribattery.lang.typecheck import TypeEnv, type_of

#: A model with reward structures: as written, or flattened.
_Rewarded = TypeVar("_Rewarded", Model, FlatModel)


def is_index(selector: str) -> bool:
    """Whether *selector* reads as a property index (``3``; ``-1`` too, which is out of
    range: with a properties file a bare integer picks, it is not a constant property)."""
    return selector.removeprefix("-").isdigit()


def select_properties(props: PropertiesFile, selector: str) -> tuple[Property, ...]:
    """The properties picked by *selector*: a 1-based index (as PRISM's ``-prop``), a
    property name, or several of these separated by commas.

    :raises PrismSemanticError: for an index out of range or an unknown name
    """
    return tuple(_select_one(props, part.strip()) for part in selector.split(","))


def _select_one(props: PropertiesFile, selector: str) -> Property:
    count = len(props.properties)
    if is_index(selector):
        index = int(selector)
        if not 1 <= index <= count:
            raise PrismSemanticError(
                f"there is no property {index} in {props.source} (it has {count} properties)"
            )
        return props.properties[index - 1]
    name = selector.strip('"')
    for prop in props.properties:
        if prop.name == name:
            return prop
    named = ", ".join(f'"{p.name}"' for p in props.properties if p.name) or "none"
    raise PrismSemanticError(
        f'there is no property named "{name}" in {props.source} (named properties: {named})'
    )


class _Resolver:
    """Substitutes one properties file's names into formulas, checking each use."""

    def __init__(
        self, model: FlatModel, props: PropertiesFile | None, given: Mapping[str, Value | str]
    ) -> None:
        self.model = model
        self.props = props or PropertiesFile((), (), (), model.source)
        model_values = dict(model.constants)
        own = _own(given, self.props.constants)
        self.table = ConstantTable(self.props.constants, own, model_values)
        self.types = {**_value_types(model_values), **_decl_types(self.props.constants)}
        self.formulas = {f.name: f.expr for f in model.formulas}
        self.model_labels = {lab.name for lab in model.labels}
        self.labels = {lab.name: lab.expr for lab in self.props.labels}
        self.named = {p.name: p for p in self.props.properties if p.name is not None}
        self.variables: dict[str, ValueType] = {
            v.name: "bool" if v.is_bool else "int" for v in model.variables
        }
        self._check_names()

    def _check_names(self) -> None:
        check_unique(((c.name, c.span) for c in self.props.constants), "constant")
        for decl in self.props.constants:
            taken = (dict(self.model.constants), self.variables, self.formulas)
            if any(decl.name in names for names in taken):
                raise PrismSemanticError(
                    f"'{decl.name}' is already defined in the model", decl.span
                )
        check_unique(((lab.name, lab.span) for lab in self.props.labels), "label")
        for lab in self.props.labels:
            if lab.name in self.model_labels or lab.name in BUILTIN_LABELS:
                raise PrismSemanticError(f'label "{lab.name}" is already defined', lab.span)

    def resolve(self, node: Any, stack: tuple[str, ...] = ()) -> Any:
        """*node* with constants, formulas, file labels and named properties inlined."""

        def replace(sub: Any) -> Any | None:
            if isinstance(sub, Ident):
                return self._ident(sub)
            if isinstance(sub, LabelRef):
                return self._label(sub, stack)
            return None

        return substitute(node, replace)

    def _ident(self, ident: Ident) -> Expr | None:
        if ident.name in self.types:
            return literal(self.table.value(ident.name), ident.span, self.types[ident.name])
        if ident.name in self.formulas:
            return self.formulas[ident.name]
        if ident.name in self.variables:
            return None
        raise PrismSemanticError(f"unknown identifier '{ident.name}'", ident.span)

    def _label(self, ref: LabelRef, stack: tuple[str, ...]) -> Expr | None:
        if ref.name in self.model_labels or ref.name in BUILTIN_LABELS:
            return None
        if ref.name in stack:
            raise PrismSemanticError(f'label "{ref.name}" refers to itself', ref.span)
        if ref.name in self.labels:
            return cast(Expr, self.resolve(self.labels[ref.name], (*stack, ref.name)))
        if ref.name in self.named and self.named[ref.name].unsupported is None:
            return cast(Expr, self.resolve(self.named[ref.name].formula, (*stack, ref.name)))
        known = sorted(self.model_labels | self.labels.keys() | BUILTIN_LABELS)
        raise PrismSemanticError(
            f'unknown label "{ref.name}" (known labels: {", ".join(known)})', ref.span
        )


def _own(given: Mapping[str, Value | str], decls: tuple[ConstDecl, ...]) -> dict[str, Value | str]:
    names = {d.name for d in decls}
    return {k: v for k, v in given.items() if k in names}


def _value_types(values: Mapping[str, Value]) -> dict[str, ValueType]:
    def kind(value: Value) -> ValueType:
        if isinstance(value, bool):
            return "bool"
        return "int" if isinstance(value, int) else "double"

    return {name: kind(value) for name, value in values.items()}


def _decl_types(decls: tuple[ConstDecl, ...]) -> dict[str, ValueType]:
    return {d.name: d.type for d in decls}


def _check_reward(op: RewardOp | RewardBounded, model: FlatModel) -> None:
    if op.reward == STEPS_REWARD:
        return
    names = [r.name for r in model.rewards]
    if not names:
        raise PrismSemanticError(
            "the R operator needs a reward structure, and the model has none", op.span
        )
    if isinstance(op.reward, str) and op.reward not in names:
        known = ", ".join(f'"{n}"' for n in names if n is not None) or "only unnamed ones"
        raise PrismSemanticError(
            f'unknown reward structure "{op.reward}" (the model has {known})', op.span
        )
    if isinstance(op.reward, int) and not 0 <= op.reward < len(names):
        raise PrismSemanticError(
            f"there is no reward structure {op.reward + 1} (the model has {len(names)})", op.span
        )


def _check_bound(op: ProbOp | RewardOp | SteadyOp) -> None:
    if op.bound is None:
        return
    value = evaluate(op.bound, {})
    if isinstance(op, ProbOp | SteadyOp) and not 0 <= value <= 1:
        raise PrismSemanticError(f"the probability bound {value} is not in [0, 1]", op.bound.span)


def _check_steps(value: Expr, kind: str = "step") -> None:
    if evaluate(value, {}) < 0:
        raise PrismSemanticError(f"a {kind} bound cannot be negative", value.span)


def _check_interval(node: TimeBound | TimeInterval, kind: str = "step") -> None:
    """PRISM rejects a step interval that holds no step (``F<0``, ``G[1,0]``); a reward
    bound (*kind* ``reward``) that admits no total alike."""
    for value in (node.low, node.high) if isinstance(node, TimeInterval) else (node.value,):
        _check_steps(value, kind)
    if isinstance(node, TimeInterval):
        low, high = evaluate(node.low, {}), evaluate(node.high, {})
    elif node.op == "=":
        low = high = evaluate(node.value, {})
    elif node.op in ("<", "<="):
        low, high = 0, evaluate(node.value, {}) - (node.op == "<")
    else:
        low, high = evaluate(node.value, {}) + (node.op == ">"), None
    if high is not None and high < low:
        raise PrismSemanticError(
            f"the {kind} bound holds for no {'total' if kind == 'reward' else 'step'} (the "
            f"interval [{low},{high}] is empty)",
            node.span)


def _check_multi(formula: Expr, model: FlatModel) -> None:
    """PRISM's rules for ``multi(...)``: the whole property, on an MDP, at most one
    objective asking ``=?`` (two or more ask for a Pareto curve: not supported)."""
    found = [node for node in walk(formula) if isinstance(node, Multi)]
    if not found:
        return
    multi = found[0]
    if formula is not multi or len(found) > 1:
        raise PrismSemanticError("multi(...) must be the whole property", found[-1].span)
    if model.model_type != "mdp":
        raise PrismSemanticError(
            f"multi(...) is for MDPs (strategies), not a {model.model_type}", multi.span)
    queried = [o for o in multi.objectives if isinstance(o, ProbOp | RewardOp) and o.op == "=?"]
    if len(queried) > 1:
        raise PrismSemanticError("Pareto queries (multi(...) with more than one =? objective) "
                                 "are not supported", queried[1].span)


def _check_operators(formula: Expr, model: FlatModel) -> None:
    _check_multi(formula, model)
    on_rewards = {id(node.bound) for node in walk(formula) if isinstance(node, RewardBounded)}
    for node in walk(formula):
        if isinstance(node, RewardOp | RewardBounded):
            _check_reward(node, model)
        if isinstance(node, ProbOp | RewardOp | SteadyOp):
            _check_bound(node)
        elif isinstance(node, TimeBound | TimeInterval):
            _check_interval(node, "reward" if id(node) in on_rewards else "step")
        elif isinstance(node, Cumulative):
            _check_steps(node.bound)
        elif isinstance(node, Instantaneous):
            _check_steps(node.time)


def resolve_property(
    prop: Property,
    model: FlatModel,
    props: PropertiesFile | None = None,
    constants: Mapping[str, Value | str] | None = None,
) -> Property:
    """*prop* made closed over *model*: only variables, literals and model/built-in labels.

    Constants (the model's, then the properties file's, with *constants* for the
    undefined ones) become literals; the model's formulas and the file's labels
    (and named properties used as ``"name"``) are inlined; types, labels, reward
    structures and bounds are checked.

    :raises PrismSemanticError: for an unsupported construct or any of those errors
    :raises ArgumentError: for a model not flattened, or *constants* that are no mapping
    """
    model = require_flat(model)
    require_constants(constants)
    if prop.unsupported is not None:
        raise PrismSemanticError(f"unsupported property {prop.text}: {prop.unsupported}", prop.span)
    resolver = _Resolver(model, props, constants or {})
    formula = cast(Expr, resolver.resolve(prop.formula))
    type_of(formula, TypeEnv(resolver.variables, in_property=True))
    formula = _valued_booleans(cast(Expr, fold(formula)), resolver.variables)
    _check_operators(formula, model)
    return Property(formula, prop.name, prop.text, prop.span)


def _valued_booleans(formula: Expr, variables: Mapping[str, ValueType]) -> Expr:
    """*formula* with each boolean variable ``b`` read as ``b=true``: the state table
    stores booleans as 0/1, so a property whose value is a variable's (``b``, or
    ``filter(print, b)``) would otherwise be reported as the number 1, not ``true``."""

    def replace(node: Any) -> Any | None:
        if type(node) is Ident and variables.get(node.name) == "bool":
            return Binary("=", node, BoolLit(True, node.span), node.span)
        return None

    return cast(Expr, substitute(formula, replace))


def with_used_rewards(flat: _Rewarded, properties: Sequence[Property]) -> _Rewarded:
    """*flat* with only the reward structures the properties use: the others dropped
    when every property names its structure, else (``R{2}``, or ``R`` for the first)
    left without items, so that every position still names the same structure and no
    unused structure is evaluated (egl's two: most of its build). A :class:`Model` as
    written is cut the same way as its flattened :class:`FlatModel` (the exact
    builders read both, structure by structure)."""
    names: set[str] = set()
    positions: set[int] = set()
    for prop in properties:
        for node in walk(prop.formula):
            if isinstance(node, RewardOp | RewardBounded):
                if isinstance(node.reward, str):
                    names.add(node.reward)
                else:
                    positions.add(0 if node.reward is None else node.reward)
    used = [r.name in names or i in positions for i, r in enumerate(flat.rewards)]
    if all(used):
        return flat
    pairs = zip(flat.rewards, used, strict=True)
    if not positions:
        return dataclasses.replace(flat, rewards=tuple(r for r, u in pairs if u))
    return dataclasses.replace(
        flat, rewards=tuple(r if u else dataclasses.replace(r, items=()) for r, u in pairs))
