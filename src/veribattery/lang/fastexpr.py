"""The fast parser's expressions: precedence climbing, P/R/S operators, temporal paths.

See :mod:`veribattery.lang.fastparse` for how it relates to lark; this module holds
the part of :class:`ExprParser` shared by model and properties files.
"""

from __future__ import annotations

import re
from bisect import bisect_right
from collections.abc import Callable
from typing import Any

from veribattery.errors import Span
from veribattery.lang.lexer import KEYWORDS, Fallback, RuleMeta, Word, tokenize
from veribattery.lang.nodes import BoolLit, DoubleLit, Ident, IntLit, LabelRef
from veribattery.lang.transform import ToNodes, binary, call, ite, unary

__all__ = ["ExprParser"]

# What lark's RELEASE terminal matches (then ``R`` after an operand is "release").
_RELEASE = re.compile(r"R(?![A-Za-z0-9_])(?!\s*(\{|=\?|[<>]=?[^\[\];]*\[))")
# What lark's QUANTIFIER terminal matches (CTL's A [..] and E [..]).
_QUANTIFIER = re.compile(r"[AE](?=\s*\[)")
_FUNCTIONS = frozenset({"min", "max", "floor", "ceil", "pow", "mod", "log", "round"})
#: Binary operators and their level in the precedence chain (loosest first).
_LEVEL = {
    "=>": 3, "<=>": 4, "|": 5, "&": 6, "=": 8, "!=": 8,
    "<": 9, "<=": 9, ">": 9, ">=": 9, "+": 10, "-": 10, "*": 11, "/": 11,
}
_NOT_LEVEL = 7
_UNARY_LEVEL = 12
_BOUND_OPS = frozenset({"<", "<=", ">", ">="})
#: Tokens that end an expression: after one of them no operator continues it.
_ENDS = frozenset({")", ";", ",", "]", "}", "$", "||", "->", ":", ".."})
#: Longer int literals are left to lark's parse (Python reads at most 4,300 digits).
_LONGEST_INT = 100
_TIME_OPS = frozenset({"<", "<=", ">", ">=", "="})


class ExprParser:
    """Recursive descent over the token lists; ``self.i`` is the next token."""

    def __init__(self, text: str, source: str) -> None:
        self.text, self.source = text, source
        self.kinds, self.texts, self.starts = tokenize(text)
        self.newlines = [m.start() for m in re.finditer("\n", text)]
        self.rules = ToNodes(text, source)
        self.i = 0
        self.spans: dict[int, Span] = {}
        self.matches: dict[int, int] | None = None  # "(" -> ")", made when first needed

    # ------------------------------------------------------------ positions

    def span(self, index: int) -> Span:
        """The span of token *index* (shared: many nodes start at the same token)."""
        span = self.spans.get(index)
        if span is None:
            pos = self.starts[index]
            line = bisect_right(self.newlines, pos)
            column = pos - (self.newlines[line - 1] if line else -1)
            span = self.spans[index] = Span(line + 1, column, self.source)
        return span

    def meta(self, index: int) -> RuleMeta:
        span = self.span(index)
        last = max(self.i - 1, index)
        end = self.starts[last] + len(self.texts[last])
        return RuleMeta(span.line, span.col, self.starts[index], end)

    def word(self) -> Word:
        """The current token as a rule's child; advances."""
        word = Word(self.texts[self.i])
        word.end_pos = self.starts[self.i] + len(word)
        self.i += 1
        return word

    # ---------------------------------------------------------------- tokens

    def expect(self, kind: str) -> None:
        if self.kinds[self.i] != kind:
            raise Fallback
        self.i += 1

    def at_word(self, *words: str) -> bool:
        return self.kinds[self.i] == "I" and self.texts[self.i] in words

    def expect_word(self, word: str) -> None:
        if not self.at_word(word):
            raise Fallback
        self.i += 1

    def name(self) -> Word:
        """A name (IDENT) that is no keyword."""
        if self.kinds[self.i] != "I" or self.texts[self.i] in KEYWORDS:
            raise Fallback
        return self.word()

    def string(self) -> Word:
        if self.kinds[self.i] != "S":
            raise Fallback
        return self.word()

    # ----------------------------------------------------------- expressions

    def expr(self) -> Any:
        """``temporal_binary``: ``a U b``, ``a W b`` (``R`` as release goes to lark)."""
        start = self.i
        left = self.temporal_unary()
        if self.kinds[self.i] == "I":
            word = self.texts[self.i]
            if word in ("U", "W"):
                op = self.word()
                if self.kinds[self.i] == "{":
                    return self.reward_bounded(start, [left, op], word == "U")
                bound = self.time_bound()
                right = self.temporal_unary()
                children = [left, op, right] if bound is None else [left, op, bound, right]
                return self.rules.temporal_binop(self.meta(start), children)
            if word == "R" and _RELEASE.match(self.text, self.starts[self.i]):
                raise Fallback
        return left

    def temporal_unary(self) -> Any:
        if not self.at_word("X", "F", "G"):
            return self.ternary()
        start = self.i
        op = self.word()
        if self.kinds[self.i] == "{":
            return self.reward_bounded(start, [op], op == "F")
        bound = self.time_bound()
        operand = self.temporal_unary()
        children = [op, operand] if bound is None else [op, bound, operand]
        return self.rules.temporal_unop(self.meta(start), children)

    def reward_bounded(self, start: int, children: list[Any], allowed: bool) -> Any:
        """``F{"r"}<=T phi`` or ``a U{"r"}<=T b`` (Storm's reward bounds)."""
        if not allowed:
            raise Fallback
        children.append(self.reward_name())
        bound = self.time_bound()
        if bound is None:
            raise Fallback
        children += [bound, self.temporal_unary()]
        rule = self.rules.reward_bounded_binop if len(children) == 5 else (
            self.rules.reward_bounded_unop)
        return rule(self.meta(start), children)

    def time_bound(self) -> Any:
        """An optional step bound ``<=k`` (k a sum) or interval ``[a,b]``."""
        start, kind = self.i, self.kinds[self.i]
        if kind in _TIME_OPS:
            op = self.word()
            return self.rules.time_bound(self.meta(start), [op, self.binary(10)])
        if kind == "[":
            self.i += 1
            low = self.expr()
            self.expect(",")
            high = self.expr()
            self.expect("]")
            return self.rules.time_interval(self.meta(start), [low, high])
        return None

    def ternary(self) -> Any:
        """``c1 ? v1 : c2 ? v2 : ... : d``, read in a loop, as is a parenthesised
        last branch ``c1 ? v1 : (c2 ? v2 : (...))``: a value per cell of a large farm
        is a chain thousands long, and recursion would stop at a few hundred."""
        # Per open parenthesis (the outermost level has none): where it is, and
        # the links (condition, value, start) read at that level.
        levels: list[tuple[int, list[tuple[Any, Any, int]]]] = [(-1, [])]
        while True:
            start = self.i
            cond = self.binary(3)
            if self.kinds[self.i] == "?":
                self.i += 1
                then = self.binary(3)
                self.expect(":")
                levels[-1][1].append((cond, then, start))
                if self.closing_group():
                    levels.append((self.i, []))
                    self.i += 1
                continue
            result = _chain(levels[-1][1], cond, self.span)
            while True:
                paren, _ = levels.pop()
                if paren < 0:
                    return result
                if self.kinds[self.i] == ")":
                    self.i += 1
                else:  # not a chain after all, e.g. "(a U b)": read the group as usual
                    self.i = paren
                    result = self.atom()
                result = _chain(levels[-1][1], result, self.span)

    def closing_group(self) -> bool:
        """Whether a parenthesised group starts here and ends the expression (what
        follows its ``)`` cannot continue it), so that it is the last branch."""
        if self.kinds[self.i] != "(":
            return False
        if self.matches is None:
            self.matches = _matching_parentheses(self.kinds)
        close = self.matches.get(self.i)
        return close is not None and self.kinds[close + 1] in _ENDS

    def binary(self, level: int) -> Any:
        """The rule at *level* of the chain (3 ``=>`` ... 11 ``*``; 12 and up: unary)."""
        if level >= _UNARY_LEVEL:
            return self.unary()
        kinds = self.kinds
        start = self.i
        if kinds[start] == "!" and level <= _NOT_LEVEL:
            self.i += 1
            left = unary("!", self.binary(_NOT_LEVEL), self.span(start))
        else:
            left = self.unary()
        while True:
            op = kinds[self.i]
            op_level = _LEVEL.get(op)
            if op_level is None or op_level < level:
                return left
            self.i += 1
            left = binary(left, op, self.binary(op_level + 1), self.span(start))

    def unary(self) -> Any:
        start = self.i
        if self.kinds[start] == "-":
            self.i += 1
            return unary("-", self.unary(), self.span(start))
        base = self.atom()
        if self.kinds[self.i] != "^":
            return base
        self.i += 1
        return binary(base, "^", self.unary(), self.span(start))

    def atom(self) -> Any:
        i = self.i
        kind = self.kinds[i]
        if kind == "I":
            return self.word_atom()
        if kind == "N":
            if len(self.texts[i]) > _LONGEST_INT:
                raise Fallback  # lark's parse says why, where
            self.i += 1
            return IntLit(int(self.texts[i]), self.span(i))
        if kind == "D":
            self.i += 1
            return DoubleLit(float(self.texts[i]), self.texts[i], self.span(i))
        if kind == "S":
            self.i += 1
            return LabelRef(self.texts[i][1:-1], self.span(i))
        if kind == "(":
            self.i += 1
            inner = self.expr()
            self.expect(")")
            return inner
        raise Fallback

    def word_atom(self) -> Any:
        i = self.i
        word = self.texts[i]
        if word not in KEYWORDS:
            if self.kinds[i + 1] == "=?":
                return self.steps_op()
            self.i += 1
            return Ident(word, self.span(i))
        if word in ("true", "false"):
            self.i += 1
            return BoolLit(word == "true", self.span(i))
        if word in _FUNCTIONS:
            self.i += 1
            self.expect("(")
            return call(word, self.arguments([self.expr()]), self.span(i))
        if word == "func":
            self.i += 1
            self.expect("(")
            if not self.at_word(*_FUNCTIONS):
                raise Fallback
            name = self.texts[self.i]
            self.i += 1
            return call(name, self.arguments([]), self.span(i))
        return self.operator(word)

    def arguments(self, args: list[Any]) -> list[Any]:
        """The rest of ``(a, b, ...)``: ``, expr`` repeated, then ``)``."""
        while self.kinds[self.i] == ",":
            self.i += 1
            args.append(self.expr())
        self.expect(")")
        return args

    # ------------------------------------------------------ P, R, S operators

    def operator(self, word: str) -> Any:
        start = self.i
        self.i += 1
        if word in ("P", "Pmin", "Pmax"):
            return self.prob_op(start, self.query())
        if word in ("R", "Rmin", "Rmax"):
            reward = self.reward_name()
            if word == "R" and reward is not None and self.at_word_ahead(0, "min", "max"):
                self.i += 1  # R{"r"}min: the direction read by the rule from the text
            query = self.query()
            self.expect("[")
            children = [query, self.reward_path()]
            if reward is not None:
                children.insert(0, reward)
            return self.rules.reward_op(self.meta(start), self.close_operator(children))
        if word == "S":
            query = self.query()
            self.expect("[")
            children = [query, self.expr()]
            return self.rules.steady_op(self.meta(start), self.close_operator(children))
        if word in ("A", "E") and _QUANTIFIER.match(self.text, self.starts[start]):
            self.expect("[")
            path = self.expr()
            self.expect("]")
            return self.rules.quantified(self.meta(start), [self.texts[start], path])
        if word == "filter":
            return self.filter(start)
        raise Fallback  # a keyword used as a name

    def prob_op(self, start: int, query: Any) -> Any:
        """The rest of ``P~ [ path ]`` or Storm's ``P=? [ path || F cond ]``."""
        self.expect("[")
        children = [query, self.expr()]
        rule = self.rules.prob_op
        if self.kinds[self.i] == "||":
            children += [self.word(), self.expr()]
            rule = self.rules.conditional_prob_op
        return rule(self.meta(start), self.close_operator(children))

    def close_operator(self, children: list[Any]) -> list[Any]:
        """An optional old-style ``{states}{min}{max}`` filter, then ``]``."""
        if self.kinds[self.i] == "{":
            start = self.i
            self.i += 1
            states = [self.expr()]
            self.expect("}")
            while self.kinds[self.i] == "{" and self.kinds[self.i + 2] == "}":
                if not self.at_word_ahead(1, "min", "max"):
                    break
                op_start = self.i
                self.i += 3
                states.append(self.rules.legacy_op(self.meta(op_start),
                                                   ["{", self.texts[op_start + 1], "}"]))
            children.append(self.rules.state_filter(self.meta(start), states))
        self.expect("]")
        return children

    def at_word_ahead(self, ahead: int, *words: str) -> bool:
        index = self.i + ahead
        return self.kinds[index] == "I" and self.texts[index] in words

    def steps_op(self) -> Any:
        """``T=? [ F phi ]`` (any name: the rule says which ones it knows)."""
        start = self.i
        children: list[Any] = [self.word(), self.word()]
        self.expect("[")
        children.append(self.reward_path())
        return self.rules.steps_op(self.meta(start), self.close_operator(children))

    def filter(self, start: int) -> Any:
        """``filter(op, phi[, states])``."""
        self.expect("(")
        op_start, kind = self.i, self.kinds[self.i]
        word = self.texts[op_start]
        if kind in ("+", "&", "|") or (kind == "I" and (word not in KEYWORDS or word in (
                "min", "max"))):
            op = self.rules.filter_op(self.meta(op_start), [self.word()])
        else:
            raise Fallback
        self.expect(",")
        children = [op, self.expr()]
        if self.kinds[self.i] == ",":
            self.i += 1
            children.append(self.expr())
        self.expect(")")
        return self.rules.filter(self.meta(start), children)

    def query(self) -> Any:
        start, kind = self.i, self.kinds[self.i]
        if kind == "=?":
            self.i += 1
            return self.rules.query_value(self.meta(start), [])
        if kind in _BOUND_OPS:
            op = self.word()
            return self.rules.query_bound(self.meta(start), [op, self.binary(10)])
        raise Fallback

    def reward_name(self) -> str | int | None:
        if self.kinds[self.i] != "{":
            return None
        start = self.i
        self.i += 1
        kind = self.kinds[self.i]
        if kind == "S":
            name: str | int = self.rules.reward_by_name(self.meta(start), [self.word()])
        elif kind == "N":
            name = self.rules.reward_by_index(self.meta(start), [self.word()])
        else:
            raise Fallback
        self.expect("}")
        return name

    def reward_path(self) -> Any:
        start = self.i
        if self.at_word("C"):
            self.i += 1
            bound = self.time_bound()
            return self.rules.cumulative(self.meta(start), [] if bound is None else [bound])
        if self.at_word("I"):
            self.i += 1
            bound = self.time_bound()
            if bound is None:
                raise Fallback
            return self.rules.instantaneous(self.meta(start), [bound])
        if self.at_word("S") and self.kinds[self.i + 1] == "]":
            self.i += 1
            return self.rules.steady_reward(self.meta(start), [])
        path = self.expr()
        if self.kinds[self.i] != "||":
            return self.rules.reach(self.meta(start), [path])
        children = [path, self.word(), self.expr()]
        return self.rules.conditional_reach(self.meta(start), children)



def _chain(links: list[tuple[Any, Any, int]], last: Any, span: Callable[[int], Span]) -> Any:
    """``c1 ? v1 : c2 ? v2 : ... : last`` from its links, innermost first."""
    result = last
    for cond, then, start in reversed(links):
        result = ite(cond, then, result, span(start))
    return result


def _matching_parentheses(kinds: list[str]) -> dict[int, int]:
    """The index of each ``(``'s matching ``)`` (unbalanced ones are left out)."""
    matches: dict[int, int] = {}
    opened: list[int] = []
    for index, kind in enumerate(kinds):
        if kind == "(":
            opened.append(index)
        elif kind == ")" and opened:
            matches[opened.pop()] = index
    return matches
