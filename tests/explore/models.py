"""Hand-built flat models for the explorer tests (independent of the parser).

``expr("x<N-1 & y=0")`` parses a small PRISM expression (precedence as PRISM's);
``flat_model(...)`` assembles a FlatModel from compact descriptions.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

from veribattery.errors import Span
from veribattery.lang.nodes import (
    Assignment,
    Binary,
    BoolLit,
    Call,
    Command,
    DoubleLit,
    Expr,
    FlatModel,
    FlatModule,
    Ident,
    IntLit,
    Ite,
    LabelDecl,
    RewardItem,
    RewardStruct,
    Unary,
    Update,
    Variable,
)

_TOKEN = re.compile(r"\s*(\d+\.\d*|\d+|[A-Za-z_]\w*|<=>|=>|<=|>=|!=|[-+*/()<>=!&|?:,])")
_LEVELS: list[tuple[str, ...]] = [
    ("<=>",),
    ("=>",),
    ("|",),
    ("&",),
    ("=", "!="),
    ("<", "<=", ">", ">="),
    ("+", "-"),
    ("*", "/"),
]


class _Parser:
    def __init__(self, text: str) -> None:
        self.tokens = _TOKEN.findall(text)
        self.pos = 0

    def peek(self) -> str | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def take(self) -> str:
        self.pos += 1
        return self.tokens[self.pos - 1]

    def ite(self) -> Expr:
        cond = self.binary(0)
        if self.peek() != "?":
            return cond
        self.take()
        then = self.ite()
        assert self.take() == ":"
        return Ite(cond, then, self.ite())

    def binary(self, level: int) -> Expr:
        if level == len(_LEVELS):
            return self.unary()
        left = self.binary(level + 1)
        while self.peek() in _LEVELS[level]:
            op = self.take()
            left = Binary(op, left, self.binary(level + 1))  # type: ignore[arg-type]
        return left

    def unary(self) -> Expr:
        if self.peek() in ("!", "-"):
            op = self.take()
            return Unary(op, self.unary())  # type: ignore[arg-type]
        return self.atom()

    def atom(self) -> Expr:
        token = self.take()
        if token == "(":
            inner = self.ite()
            assert self.take() == ")"
            return inner
        if token[0].isdigit():
            return DoubleLit(float(token), token) if "." in token else IntLit(int(token))
        if token in ("true", "false"):
            return BoolLit(token == "true")
        if self.peek() == "(":
            self.take()
            args = [self.ite()]
            while self.take() == ",":
                args.append(self.ite())
            return Call(token, tuple(args))  # type: ignore[arg-type]
        return Ident(token, Span(1, 1 + self.pos))


def expr(text: str) -> Expr:
    """Parse a small PRISM expression."""
    parser = _Parser(text)
    result = parser.ite()
    assert parser.peek() is None, f"trailing tokens in {text!r}"
    return result


def command(
    guard: str,
    updates: Sequence[tuple[str, Mapping[str, str]]],
    action: str | None = None,
    line: int = 1,
) -> Command:
    """``[action] guard -> p1:(x'=e)&... + ...;`` with the command at *line*."""
    return Command(
        action=action,
        guard=expr(guard),
        updates=tuple(
            Update(expr(p), tuple(Assignment(v, expr(e)) for v, e in assignments.items()))
            for p, assignments in updates
        ),
        span=Span(line, 3, "test.pm"),
    )


def var(name: str, low: int, high: int, init: int | None = None, module: str = "M") -> Variable:
    """An int variable (init defaults to *low*)."""
    return Variable(name, low, high, low if init is None else init, False, module)


def boolean(name: str, init: bool = False, module: str = "M") -> Variable:
    """A bool variable."""
    return Variable(name, 0, 1, int(init), True, module)


def module(name: str, variables: Sequence[str], commands: Sequence[Command]) -> FlatModule:
    """A flat module; its alphabet is its commands' actions."""
    alphabet = frozenset(c.action for c in commands if c.action is not None)
    return FlatModule(name, tuple(variables), tuple(commands), alphabet)


def rewards(
    name: str | None, *items: tuple[str | None, str, str] | tuple[str, str]
) -> RewardStruct:
    """A reward structure: ``("g", "v")`` is a state item, ``(action, "g", "v")`` a
    transition item (action None for ``[]``)."""
    built = []
    for item in items:
        if len(item) == 2:
            built.append(RewardItem(False, None, expr(item[0]), expr(item[1])))
        else:
            action, guard, value = item
            built.append(RewardItem(True, action, expr(guard), expr(value)))  # type: ignore[arg-type]
    return RewardStruct(name, tuple(built))


def flat_model(
    variables: Sequence[Variable],
    modules: Sequence[FlatModule],
    labels: Mapping[str, str] | None = None,
    reward_structs: Sequence[RewardStruct] = (),
    init: str | None = None,
) -> FlatModel:
    """Assemble a FlatModel."""
    return FlatModel(
        variables=tuple(variables),
        modules=tuple(modules),
        labels=tuple(LabelDecl(n, expr(e)) for n, e in (labels or {}).items()),
        rewards=tuple(reward_structs),
        constants=(),
        formulas=(),
        init=None if init is None else expr(init),
    )
