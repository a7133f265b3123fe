"""Constants: ``--const`` parsing (values or closed expressions), typed values, and
evaluation in dependency order."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

from veribattery.errors import ArgumentError, PrismSemanticError, PrismSyntaxError
from veribattery.lang.evaluate import EvaluationError, evaluate
from veribattery.lang.expressions import walk
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    ConstDecl,
    DoubleLit,
    Expr,
    Ident,
    IntLit,
    Ite,
    Unary,
    Value,
    ValueType,
)
from veribattery.lang.ops import INT_MAX, INT_MIN, OperatorError, int_literal, out_of_int_range
from veribattery.lang.typecheck import TypeEnv, type_of

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
#: An int written in digits, as ``--const N=...`` gives one.
_INT_TEXT = re.compile(r"[-+]?[0-9]+")


def parse_constant_assignments(items: Sequence[str]) -> dict[str, str]:
    """Parse CLI ``--const`` items: ``N=16``, or several at once as ``N=16,MAX=2``.

    A value may be a closed expression (``p=1/3``, ``N=max(2,3)``): commas inside
    parentheses belong to it.

    :raises PrismSemanticError: for an item that is not ``NAME=VALUE``, or a name given twice
    """
    result: dict[str, str] = {}
    for item in items:
        for part in _top_level_parts(item):
            name, sep, value = (s.strip() for s in part.partition("="))
            if not sep or not _NAME.fullmatch(name) or not value:
                raise PrismSemanticError(
                    f"malformed constant '{part.strip()}' in --const {item}: "
                    "expected NAME=VALUE, e.g. N=16"
                )
            if name in result:
                raise PrismSemanticError(f"constant '{name}' is given twice in --const")
            result[name] = value
    return result


def _top_level_parts(item: str) -> list[str]:
    """*item* split at the commas outside parentheses."""
    parts, depth, start = [], 0, 0
    for i, char in enumerate(item):
        depth += (char == "(") - (char == ")")
        if char == "," and depth == 0:
            parts.append(item[start:i])
            start = i + 1
    parts.append(item[start:])
    return parts


def _parse_text(decl: ConstDecl, text: str) -> Value:
    """The value given as *text*: a literal, or a closed expression such as ``1/3``."""
    text = text.strip()
    literal = _literal(decl, text)
    if literal is not None:
        return literal
    expr = given_expression(decl, text)
    try:
        value = evaluate(expr, {})
    except EvaluationError as exc:
        raise PrismSemanticError(
            f"constant '{decl.name}' has no value: --const {decl.name}={text}: {exc.message}"
        ) from None
    return float(value) if decl.type == "double" else value


def _literal(decl: ConstDecl, text: str) -> Value | None:
    """*text* read as a number or truth value of *decl*'s type, or None."""
    if decl.type == "bool":
        return text == "true" if text in ("true", "false") else None
    if decl.type == "int" and _INT_TEXT.fullmatch(text):
        try:  # (int() refuses more than 4,300 digits, which read as "no int" before)
            return -int_literal(text[1:]) if text[0] == "-" else int_literal(text.lstrip("+"))
        except OperatorError as exc:
            raise _given_error(decl, text, exc.message) from None
    try:
        if decl.type == "int":
            return int(text)
        if "/" in text:  # a ratio: fractions (which imports decimal) only then
            from fractions import Fraction

            return float(Fraction(text))
        return float(text)
    except (ValueError, ZeroDivisionError):
        return None


def given_expression(decl: ConstDecl, text: str) -> Expr:
    """*text*, given on the command line for *decl*, as a closed expression of its type.

    :raises PrismSemanticError: for text that is no such expression (the message
        quotes it): a syntax error, a name, a property operator or the wrong type
    """
    from veribattery.lang.parser import parse_property

    try:
        prop = parse_property(text)
    except PrismSyntaxError:
        prop = None
    closed = prop is not None and prop.name is None and all(
        type(node) in _CLOSED for node in walk(prop.formula))
    if prop is None or not closed:
        raise _wrong_value(decl, text)
    try:
        kind = type_of(prop.formula, TypeEnv({}))
    except PrismSemanticError:
        raise _wrong_value(decl, text) from None
    if not _assignable(decl.type, kind):
        raise _wrong_value(decl, text)
    return prop.formula


#: The nodes of a closed expression: literals, operators and functions.
_CLOSED = frozenset({IntLit, DoubleLit, BoolLit, Unary, Binary, Ite, Call})


def _wrong_value(decl: ConstDecl, text: str) -> PrismSemanticError:
    return PrismSemanticError(
        f"constant '{decl.name}' is {_a(decl.type)}, but was given the value '{text}'"
        + _BOOL_HINT * (decl.type == "bool")
    )


def _a(kind: ValueType) -> str:
    return {"int": "an int", "double": "a double", "bool": "a bool"}[kind]


#: PRISM spells a bool only ``true`` or ``false``; ``True``, as QComp's index.json files
#: write it, is a name to it, and nothing says so but this hint.
_BOOL_HINT = "; use true or false"


def coerce_value(decl: ConstDecl, raw: Value | str) -> Value:
    """A value given for an undefined constant, checked against its declared type."""
    if isinstance(raw, str):
        return _parse_text(decl, raw)
    if decl.type == "bool" and isinstance(raw, bool):
        return raw
    if decl.type == "int" and isinstance(raw, int) and not isinstance(raw, bool):
        return raw
    if decl.type == "double" and isinstance(raw, int | float) and not isinstance(raw, bool):
        return float(raw)
    raise PrismSemanticError(
        f"constant '{decl.name}' is {_a(decl.type)}, but was given the value {raw!r}"
    )


def _check_not_defined(decls: Sequence[ConstDecl], given: Mapping[str, Value | str]) -> None:
    for decl in decls:
        if decl.value is not None and decl.name in given:
            raise PrismSemanticError(
                f"constant '{decl.name}' is already defined and cannot be given a value",
                decl.span,
            )


def _missing_error(missing: Sequence[ConstDecl]) -> PrismSemanticError:
    # Said for the command line and for Python alike: either may have left them out.
    names = [d.name for d in missing]
    plural = "s" if len(missing) > 1 else ""
    option = ",".join(f"{name}=VALUE" for name in names)
    mapping = ", ".join(f"{name!r}: VALUE" for name in names)
    return PrismSemanticError(
        f"undefined constant{plural} {', '.join(names)}: give {'values' if plural else 'a value'}"
        f" with --const {option}, or constants={{{mapping}}} from Python",
        missing[0].span,
    )


class ConstantTable:
    """One file's constants, evaluated on demand: the order of definition is free, and
    an undefined constant needs a value only if it is used."""

    def __init__(
        self,
        decls: Sequence[ConstDecl],
        given: Mapping[str, Value | str],
        outer: Mapping[str, Value],
    ) -> None:
        _check_not_defined(decls, given)
        self.decls = {d.name: d for d in decls}
        self.given = given
        self.values: dict[str, Value] = dict(outer)
        self.pending: set[str] = set()
        types = {n: _type_of_value(v) for n, v in outer.items()}
        self.env = TypeEnv({**types, **{d.name: d.type for d in decls}})

    def value(self, name: str) -> Value:
        """The value of constant *name* (of this file or an outer one).

        The constants it is defined with are evaluated first, depth first in the
        order they appear, on a stack of its own: a chain of constants each defined
        by the next may be thousands long.
        """
        todo: list[tuple[str, bool]] = [(name, False)]
        while todo:
            current, ready = todo.pop()
            if ready:
                self.values[current] = self._evaluate(self.decls[current])
                self.pending.discard(current)
            elif current not in self.values:
                todo += self._enter(current)
        return self.values[name]

    def _enter(self, name: str) -> list[tuple[str, bool]]:
        """Start on *name*: checked, and what to do next (its constants, then itself)."""
        decl = self.decls[name]
        if name in self.pending:
            raise PrismSemanticError(f"constant '{name}' is defined in terms of itself", decl.span)
        if decl.value is None:
            if decl.name not in self.given:
                raise _missing_error([decl])
            given = self.given[decl.name]
            self.values[name] = _in_int_range(decl, coerce_value(decl, given), given)
            return []
        kind = type_of(decl.value, self.env)
        if not _assignable(decl.type, kind):
            raise PrismSemanticError(
                f"type error: constant '{decl.name}' is {_a(decl.type)}, "
                f"but its definition is {_a(kind)}",
                decl.value.span,
            )
        self.pending.add(name)
        used = [n.name for n in walk(decl.value) if isinstance(n, Ident) and n.name in self.decls]
        return [(name, True), *((n, False) for n in reversed(used))]

    def _evaluate(self, decl: ConstDecl) -> Value:
        assert decl.value is not None
        value = evaluate(decl.value, self.values)
        return float(value) if decl.type == "double" else _in_int_range(decl, value)


def _in_int_range(decl: ConstDecl, value: Value, given: Value | str | None = None) -> Value:
    """*value* of constant *decl*, unless it is an int the engine's ints cannot hold:
    then an error at its definition, or quoting the ``--const`` that *given* it."""
    if type(value) is not int or INT_MIN <= value <= INT_MAX:
        return value
    if decl.value is not None:
        raise PrismSemanticError(f"constant '{decl.name}': {out_of_int_range(value)}",
                                 decl.value.span)
    raise _given_error(decl, given if isinstance(given, str) else str(value),
                       out_of_int_range(value))


def _given_error(decl: ConstDecl, given: str, problem: str) -> PrismSemanticError:
    """*problem* of the value *given* on the command line for *decl* (quoted shortened)."""
    from veribattery._numbers import shortened  # (imports fractions: on this error only)

    return PrismSemanticError(f"constant '{decl.name}' (--const {decl.name}="
                              f"{shortened(given)}): {problem}")


def _type_of_value(value: Value) -> ValueType:
    if isinstance(value, bool):
        return "bool"
    return "int" if isinstance(value, int) else "double"


def _assignable(target: ValueType, source: ValueType) -> bool:
    """An int may be stored in a double, nothing else converts."""
    return target == source or (target == "double" and source == "int")


def require_constants(constants: object) -> None:
    """Refuse *constants* unless it is None or a mapping of constant names to values.

    :raises ArgumentError: naming what was given; for ``--const`` style ``N=3`` strings,
        the call that turns them into a mapping.
    """
    if constants is None or (isinstance(constants, Mapping)
                             and all(isinstance(name, str) for name in constants)):
        return
    texts = isinstance(constants, Sequence) and not isinstance(constants, str) and all(
        isinstance(item, str) for item in constants)
    fix = (f"veribattery.lang.parse_constant_assignments({constants!r})" if texts
           else "a dict such as {'N': 3}")
    raise ArgumentError.wrong_kind("constants", constants,
                                   "a mapping of constant names to values", fix)


def evaluate_constants(
    decls: Sequence[ConstDecl],
    given: Mapping[str, Value | str],
    outer: Mapping[str, Value] | None = None,
) -> dict[str, Value]:
    """Values of *decls* (in declaration order), using *given* for the undefined ones.

    :param outer: constants already known (the model's, for a properties file)
    :raises PrismSemanticError: missing or ill-typed values, cycles, unknown names
    """
    missing = [d for d in decls if d.value is None and d.name not in given]
    if missing:
        raise _missing_error(missing)
    table = ConstantTable(decls, given, outer or {})
    return {d.name: table.value(d.name) for d in decls}


def assignable(target: ValueType, source: ValueType) -> bool:
    """Whether a value of type *source* may be stored in a *target* (int → double only)."""
    return _assignable(target, source)
