"""Closed expressions evaluated in rationals, before flattening.

In ``--exact`` mode every expression has its exact value, as in PRISM's exact engine;
but the flattening folds closed sub-expressions in doubles, where ``1/3 = 0.333...``
(24 threes) is true and ``ceil(0.1*3*10)`` is 4. A probability keeps its exact value
(the exact builder reads it from the model as written), but a comparison or an integer
decides the state space: a guard, an update, an initial value, a constant such as
``const int n = ceil(...)``, a step bound. So before the model (or a property) is
flattened, each *closed* sub-expression -- no variable, label or formula in it -- is
replaced by the literal of its exact value: doubles then see the same decisions, and a
double literal carries its exact value as its text (``1/3``), which exact evaluation
reads. PRISM's own tests of this are prism-tests/functionality/verify/exact/.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any, TypeVar

from veribattery._numbers import nearest_float
from veribattery.explore.exact.constants import exact_constants
from veribattery.explore.exact.rational import ExactScalar, closed_value
from veribattery.lang import flatten_model, resolve_property
from veribattery.lang.expressions import children, substitute
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    DoubleLit,
    FlatModel,
    Ident,
    IntLit,
    Ite,
    Model,
    PropertiesFile,
    Property,
    RenamedModule,
    Unary,
    Value,
)
from veribattery.lang.semantics import expand_formulas, expanded_modules

__all__ = ["decided_exactly", "flattened_exactly"]

_T = TypeVar("_T")

#: The compound expressions that may be decided (a literal is its own value).
_COMPOUND = (Binary, Unary, Ite, Call)
_LITERALS = (BoolLit, IntLit, DoubleLit)


def decided_exactly(node: _T, constants: Mapping[str, ExactScalar]) -> _T:
    """*node* (a model, a property or an expression) with each maximal closed
    sub-expression, and each constant read outside one, replaced by the literal of its
    exact value (a double's text is the exact fraction).

    :param constants: the exact values of the constants it may read
        (:func:`~veribattery.explore.exact.constants.exact_constants`); any other name
        (a variable, a formula) makes an expression open.
    :raises ModelError: for a closed expression without an exact rational value (``log``,
        a power with an irrational value, a division by zero), as PRISM's exact engine.
    """
    closed = _closed_nodes(node, constants)

    def replace(sub: Any) -> Any | None:
        # A constant's name too: resolution would write its double (1/3 as 0.333...).
        if id(sub) not in closed or not isinstance(sub, (*_COMPOUND, Ident)):
            return None
        value, kind = closed_value(sub, constants)  # ModelError: no exact value (log ...)
        if kind == "bool":
            return BoolLit(bool(value), sub.span)
        if kind == "int":
            return IntLit(int(value), sub.span)
        # A double: the float nearest its value, written as the exact fraction that the
        # exact evaluation reads (resolution would fold 1/3 into 0.3333333333333333).
        return DoubleLit(nearest_float(value), f"{value.numerator}/{value.denominator}",
                         sub.span)

    return substitute(node, replace)  # type: ignore[no-any-return]


def _closed_nodes(root: Any, constants: Mapping[str, ExactScalar]) -> set[int]:
    """The ids of the expressions under *root* that read only literals and *constants*
    (children first on a stack of its own: a model's expressions nest thousands deep)."""
    closed: set[int] = set()
    stack: list[tuple[Any, tuple[Any, ...] | None]] = [(root, None)]  # None: not expanded
    seen: set[int] = set()
    while stack:
        node, kids = stack.pop()
        if kids is None:
            if id(node) in seen:
                continue
            seen.add(id(node))
            kids = tuple(children(node))
            stack.append((node, kids))
            stack.extend((kid, None) for kid in kids)
            continue
        leaf = isinstance(node, _LITERALS) or (
            isinstance(node, Ident) and node.name in constants)
        if leaf or (isinstance(node, _COMPOUND) and all(id(kid) in closed for kid in kids)):
            closed.add(id(node))
    return closed


def flattened_exactly(
    model: Model, properties: Sequence[Property], props_file: PropertiesFile | None,
    given: Mapping[str, Value | str] | None,
) -> tuple[Model, list[Property], PropertiesFile | None, FlatModel]:
    """*model*, its *properties* and their *props_file* (its labels and named
    properties) decided exactly (:func:`decided_exactly`) over the exact values of the
    model's constants and the file's (*given*: the values of the undefined ones), and the
    decided model flattened.

    :raises PrismSemanticError: as :func:`~veribattery.lang.flatten_model` and
        :func:`~veribattery.lang.resolve_property`, on the model and properties as written.
    """
    flat = flatten_model(model, given)  # names, types, missing constants: as written
    for prop in properties:  # likewise: deciding would make `true + 1` the literal 2
        resolve_property(prop, flat, props_file, given)
    given = dict(given or {})
    model_values = exact_constants(model.constants, given)
    decls = props_file.constants if props_file is not None else ()
    values = exact_constants(decls, given, outer=model_values)
    decided = [replace(p, formula=decided_exactly(p.formula, values)) for p in properties]
    expanded = _renamings_expanded(model)
    decided_model = decided_exactly(expanded, model_values)
    if decided_model is not model:
        flat = flatten_model(decided_model, given)
    return (decided_model, decided,
            None if props_file is None else decided_exactly(props_file, values), flat)


def _renamings_expanded(model: Model) -> Model:
    """*model* with each renamed module written out (formulas inlined first, as
    flattening does): a renaming may rename a constant (``p1=p2``), which deciding the
    base module first would have replaced by its value, so the copy read *p1*'s."""
    if not any(isinstance(module, RenamedModule) for module in model.modules):
        return model
    modules = expanded_modules(model, expand_formulas(model.formulas))
    return replace(model, modules=tuple(modules))
