"""Semantic analysis of a model: names, types, ranges; the syntax tree → :class:`FlatModel`.

The order follows PRISM: formulas are expanded (inlined) first, then renamed
modules are built from their base module (so a formula used in the base module
is renamed along with it), then constants are replaced by their values.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Any, cast

from veribattery._collector import collections_spaced
from veribattery.errors import ArgumentError, PrismSemanticError, Span
from veribattery.lang.constants import assignable, evaluate_constants, require_constants
from veribattery.lang.evaluate import evaluate
from veribattery.lang.expressions import Memo, close, rename_idents, substitute, walk
from veribattery.lang.nodes import (
    Command,
    ConstDecl,
    Expr,
    FlatModel,
    FlatModule,
    FormulaDecl,
    Ident,
    LabelDecl,
    LabelRef,
    Model,
    Module,
    PropertiesFile,
    RenamedModule,
    RewardItem,
    RewardStruct,
    Update,
    Value,
    ValueType,
    VarDecl,
    Variable,
)
from veribattery.lang.ops import INT_MAX, INT_MIN, show_int
from veribattery.lang.typecheck import TypeEnv, expect, type_of

BUILTIN_LABELS = frozenset({"init", "deadlock"})


def undefined_constants(model: Model, props: PropertiesFile | None = None) -> tuple[str, ...]:
    """Names of the constants declared without a value, the model's first."""
    decls = [*model.constants, *(props.constants if props else ())]
    return tuple(d.name for d in decls if d.value is None)


def check_unique(items: Iterable[tuple[str, Span]], what: str) -> None:
    """Raise on the second occurrence of a name."""
    seen: dict[str, Span] = {}
    for name, span in items:
        if name in seen:
            raise PrismSemanticError(
                f"duplicate {what} '{name}' (first defined at {seen[name]})", span
            )
        seen[name] = span


# ------------------------------------------------------------------ formulas


def expand_formulas(formulas: Sequence[FormulaDecl]) -> dict[str, Expr]:
    """Each formula's body with the formulas it uses inlined (cycles are errors).

    Depth first on a stack of its own: a chain of formulas each using the next may
    be thousands long.
    """
    defs = {f.name: f for f in formulas}
    done: dict[str, Expr] = {}
    uses: dict[str, set[str]] = {}
    for formula in formulas:
        path: list[str] = []  # the formulas being expanded, outermost first
        todo: list[tuple[str, bool]] = [(formula.name, False)]
        while todo:
            name, ready = todo.pop()
            if ready:
                inner = {n: done[n] for n in uses[name]}
                done[name] = rename_idents(defs[name].expr, inner)
                path.pop()
                continue
            if name in path:
                chain = " -> ".join((*path, name))
                raise PrismSemanticError(f"cyclic formula definition: {chain}", defs[name].span)
            if name in done:
                continue
            used = {n.name for n in walk(defs[name].expr) if isinstance(n, Ident)} & defs.keys()
            uses[name] = used
            path.append(name)
            todo.append((name, True))
            todo.extend((n, False) for n in reversed(list(used)))
    return {f.name: done[f.name] for f in formulas}


def inline_formulas(node: Any, formulas: Mapping[str, Expr]) -> Any:
    """*node* with every identifier naming one of *formulas* replaced by its expansion."""

    def replace_ident(sub: Any) -> Any | None:
        if type(sub) is Ident and sub.name in formulas:
            return formulas[sub.name]
        return None

    return substitute(node, replace_ident)


# ---------------------------------------------------------------- renaming


def _rename_module(renamed: RenamedModule, bases: Mapping[str, Module]) -> Module:
    base = bases.get(renamed.base)
    if base is None:
        raise PrismSemanticError(
            f"module '{renamed.base}' (renamed as '{renamed.name}') is not defined", renamed.span
        )
    check_unique(((old, renamed.span) for old, _ in renamed.renames), "renaming of")
    mapping = dict(renamed.renames)

    def rename(sub: Any) -> Any | None:
        if type(sub) is Ident and sub.name in mapping:
            return Ident(mapping[sub.name], sub.span)
        return None

    def rename_all(node: Any) -> Any:
        return substitute(node, rename)

    variables = tuple(
        replace(rename_all(v), name=mapping.get(v.name, v.name)) for v in base.variables
    )
    commands = tuple(_rename_command(c, mapping, rename_all) for c in base.commands)
    return Module(renamed.name, variables, commands, renamed.span)


def _rename_command(
    command: Command, mapping: Mapping[str, str], rename_all: Callable[[Any], Any]
) -> Command:
    action = mapping.get(command.action, command.action) if command.action else None
    updates = tuple(
        replace(
            u,
            probability=rename_all(u.probability),
            assignments=tuple(
                replace(a, variable=mapping.get(a.variable, a.variable), expr=rename_all(a.expr))
                for a in u.assignments
            ),
        )
        for u in command.updates
    )
    return replace(command, action=action, guard=rename_all(command.guard), updates=updates)


def expanded_modules(model: Model, formulas: Mapping[str, Expr]) -> list[Module]:
    """All modules, formulas inlined, renamed modules expanded, in source order."""
    check_unique(((m.name, m.span) for m in model.modules), "module")
    bases = {m.name: inline_formulas(m, formulas) for m in model.modules if isinstance(m, Module)}
    return [
        bases[m.name] if isinstance(m, Module) else _rename_module(m, bases) for m in model.modules
    ]


# --------------------------------------------------------------- variables


class _Scope:
    """What flattening knows: constant values, variable owners and everyone's types."""

    def __init__(self, constants: Mapping[str, Value], decls: Sequence[ConstDecl]) -> None:
        self.values = constants
        self.const_types: dict[str, ValueType] = {d.name: d.type for d in decls}
        self.owner: dict[str, str | None] = {}
        self.var_types: dict[str, ValueType] = {}
        self._env: TypeEnv | None = None
        self._closed: Memo = {}

    def add_variable(self, var: Variable) -> None:
        self.owner[var.name] = var.module
        self.var_types[var.name] = "bool" if var.is_bool else "int"
        self._env = None

    def env(self) -> TypeEnv:
        """Constants and variables; the types of checked sub-trees are remembered."""
        if self._env is None:
            self._env = TypeEnv({**self.const_types, **self.var_types}, memo=True)
        return self._env

    def closed(self, node: Any) -> Any:
        """Constants replaced by literals, then closed sub-expressions folded."""
        return close(node, self.values, self.const_types, self._closed)

    def constant_int(self, expr: Expr, what: str) -> int:
        expect(expr, TypeEnv(self.const_types), "numeric", what)
        if type_of(expr, TypeEnv(self.const_types)) != "int":
            raise PrismSemanticError(f"type error: {what} must be an int", expr.span)
        return cast(int, evaluate(expr, self.values))


def _variable(decl: VarDecl, module: str | None, scope: _Scope, has_init_block: bool) -> Variable:
    if decl.type == "bool":
        low, high = 0, 1
    else:
        low = scope.constant_int(cast(Expr, decl.low), f"the lower bound of '{decl.name}'")
        high = scope.constant_int(cast(Expr, decl.high), f"the upper bound of '{decl.name}'")
        if low > high:
            raise PrismSemanticError(
                f"variable '{decl.name}' has an empty range [{low}..{high}]", decl.span
            )
        _check_wide(decl, low, high)
    init = _initial(decl, low, scope, has_init_block)
    if not low <= init <= high:
        raise PrismSemanticError(
            f"initial value {init} of '{decl.name}' is outside its range [{low}..{high}]",
            decl.span,
        )
    return Variable(decl.name, low, high, init, decl.type == "bool", module, decl.span)


def _check_wide(decl: VarDecl, low: int, high: int) -> None:
    """States are stored as 64-bit ints: a range must lie in the int range and hold
    fewer than 2^63 values."""
    if low >= INT_MIN and high <= INT_MAX and high - low < INT_MAX:
        return
    raise PrismSemanticError(
        f"variable '{decl.name}' has the range [{show_int(low)}..{show_int(high)}], too wide "
        "for the 64-bit ints states are stored in: its bounds must lie in -2^63..2^63-1, "
        "and it must hold fewer than 2^63 values", decl.span)


def _initial(decl: VarDecl, low: int, scope: _Scope, has_init_block: bool) -> int:
    if decl.init is None:
        return low
    if has_init_block:
        raise PrismSemanticError(
            f"variable '{decl.name}' has an init value, but the model has an init ... endinit "
            "block",
            decl.init.span,
        )
    if decl.type == "bool":
        expect(decl.init, TypeEnv(scope.const_types), "bool", f"the init value of '{decl.name}'")
        return int(bool(evaluate(decl.init, scope.values)))
    return scope.constant_int(decl.init, f"the init value of '{decl.name}'")


def _variables(model: Model, modules: Sequence[Module], scope: _Scope) -> tuple[Variable, ...]:
    owned = [(v, None) for v in model.globals] + [(v, m.name) for m in modules for v in m.variables]
    taken = [(n, c.span) for n, c in _declared_names(model)]
    check_unique([*taken, *((v.name, v.span) for v, _ in owned)], "name")
    init_block = model.init is not None
    result = tuple(_variable(v, owner, scope, init_block) for v, owner in owned)
    for var in result:
        scope.add_variable(var)
    return result


def _declared_names(model: Model) -> list[tuple[str, Any]]:
    return [(c.name, c) for c in model.constants] + [(f.name, f) for f in model.formulas]


# ---------------------------------------------------------------- commands


def _check_assignment(module: str, command: Command, var: str, scope: _Scope, span: Span) -> None:
    if var not in scope.owner:
        raise PrismSemanticError(f"'{var}' is not a variable, so it cannot be assigned", span)
    owner = scope.owner[var]
    if owner is None and command.action is not None:
        raise PrismSemanticError(
            f"global variable '{var}' cannot be updated by the synchronised command "
            f"[{command.action}] of module {module}",
            span,
        )
    if owner is not None and owner != module:
        raise PrismSemanticError(
            f"Module {module} cannot modify variable {var} of module {owner}", span
        )


def _check_update(module: str, command: Command, update: Update, scope: _Scope) -> None:
    env = scope.env()
    expect(update.probability, env, "numeric", "a probability")
    check_unique(((a.variable, a.span) for a in update.assignments), "assignment to")
    for a in update.assignments:
        _check_assignment(module, command, a.variable, scope, a.span)
        kind, target = type_of(a.expr, env), scope.var_types[a.variable]
        if not assignable(target, kind) or target == "double":
            raise PrismSemanticError(
                f"type error: cannot assign {kind} to {target} variable '{a.variable}'", a.span
            )


def _flat_module(module: Module, scope: _Scope) -> FlatModule:
    for command in module.commands:
        expect(command.guard, scope.env(), "bool", "a guard")
        for update in command.updates:
            _check_update(module.name, command, update, scope)
    commands = tuple(scope.closed(c) for c in module.commands)
    alphabet = frozenset(c.action for c in module.commands if c.action is not None)
    names = tuple(v.name for v in module.variables)
    return FlatModule(module.name, names, commands, alphabet, module.span)


# ------------------------------------------------------- labels and rewards


def _labels(model: Model, formulas: Mapping[str, Expr], scope: _Scope) -> tuple[LabelDecl, ...]:
    check_unique(((lab.name, lab.span) for lab in model.labels), "label")
    for lab in model.labels:
        if lab.name in BUILTIN_LABELS:
            raise PrismSemanticError(f'the label "{lab.name}" is built in', lab.span)
    labels = _labels_expanded([inline_formulas(lab, formulas) for lab in model.labels])
    for lab in labels:
        expect(lab.expr, scope.env(), "bool", f'label "{lab.name}"')
    return tuple(scope.closed(lab) for lab in labels)


def _labels_expanded(labels: Sequence[LabelDecl]) -> list[LabelDecl]:
    """*labels* with each reference to another of them (``label "b" = "a" & x>1``, which
    PRISM allows) replaced by that one's expression.

    :raises PrismSemanticError: for a label that refers to itself, directly or not.
    """
    declared = {lab.name: lab for lab in labels}
    expanded: dict[str, Expr] = {}

    def expression(lab: LabelDecl, path: tuple[str, ...]) -> Expr:
        if lab.name in expanded:
            return expanded[lab.name]
        if lab.name in path:
            cycle = " -> ".join(f'"{name}"' for name in (*path, lab.name))
            raise PrismSemanticError(f"labels refer to themselves: {cycle}", lab.span)

        def refer(sub: Any) -> Any | None:
            if type(sub) is not LabelRef or sub.name in BUILTIN_LABELS:
                return None
            if sub.name not in declared:
                known = ", ".join(f'"{name}"' for name in declared)
                raise PrismSemanticError(f'undeclared label "{sub.name}" (labels: {known})',
                                         sub.span)
            return expression(declared[sub.name], (*path, lab.name))

        expanded[lab.name] = substitute(lab.expr, refer)
        return expanded[lab.name]

    return [replace(lab, expr=expression(lab, ())) for lab in labels]


def _reward_item(item: RewardItem, scope: _Scope) -> RewardItem:
    expect(item.guard, scope.env(), "bool", "a reward guard")
    expect(item.value, scope.env(), "numeric", "a reward value")
    return cast(RewardItem, scope.closed(item))


def _rewards(model: Model, formulas: Mapping[str, Expr], scope: _Scope) -> tuple[RewardStruct, ...]:
    named = [(r.name, r.span) for r in model.rewards if r.name is not None]
    check_unique(named, "reward structure")
    structs = [inline_formulas(r, formulas) for r in model.rewards]
    return tuple(replace(r, items=tuple(_reward_item(i, scope) for i in r.items)) for r in structs)


# ---------------------------------------------------------------- the model


@collections_spaced
def flatten_model(model: Model, constants: Mapping[str, Value | str] | None = None) -> FlatModel:
    """Check *model* and turn it into a closed :class:`FlatModel`.

    :param constants: values for the undefined constants (str values are parsed
        per the declared type); names that the model does not declare are ignored,
        as they may belong to a properties file
    :raises PrismSemanticError: on any name, type or range error, or a missing constant
    :raises ArgumentError: for anything but a parsed model, or *constants* that are no
        mapping
    """
    if not isinstance(model, Model):
        raise ArgumentError.wrong_kind("model", model, "a parsed Model",
                                       "veribattery.parse_model(Path('model.pm'))")
    require_constants(constants)
    check_unique(((n, d.span) for n, d in _declared_names(model)), "name")
    formulas = expand_formulas(model.formulas)
    values = evaluate_constants(model.constants, _own(constants, model.constants))
    scope = _Scope(values, model.constants)
    modules = expanded_modules(model, formulas)
    variables = _variables(model, modules, scope)
    for body in formulas.values():
        type_of(body, scope.env())
    flat_modules = tuple(_flat_module(m, scope) for m in modules)
    init = None if model.init is None else _init_block(model.init, formulas, scope)
    return FlatModel(
        variables=variables,
        modules=flat_modules,
        labels=_labels(model, formulas, scope),
        rewards=_rewards(model, formulas, scope),
        constants=tuple(values.items()),
        formulas=tuple(
            FormulaDecl(f.name, scope.closed(formulas[f.name]), f.span) for f in model.formulas
        ),
        init=init,
        source=model.source,
        model_type=model.model_type,
    )


def require_flat(model: object) -> FlatModel:
    """*model*, if it is flattened (what a builder and a property's resolution read).

    :raises ArgumentError: for anything else (a parsed :class:`Model`, say).
    """
    if isinstance(model, FlatModel):
        return model
    raise ArgumentError.wrong_kind("model", model, "a flattened model",
                                   "veribattery.flatten_model(model, constants)")


def _own(
    given: Mapping[str, Value | str] | None, decls: Sequence[ConstDecl]
) -> dict[str, Value | str]:
    names = {d.name for d in decls}
    return {k: v for k, v in (given or {}).items() if k in names}


def _init_block(init: Expr, formulas: Mapping[str, Expr], scope: _Scope) -> Expr:
    expr = inline_formulas(init, formulas)
    expect(expr, scope.env(), "bool", "the init ... endinit expression")
    return cast(Expr, scope.closed(expr))
