"""The fast parser's tokenizer: one regex for the terminals of ``prism.lark``.

Context-free, unlike lark's contextual lexer: a name spelled like a keyword is a
``I`` token like any other, and the parser sends the text to lark (:class:`Fallback`)
wherever lark would have to decide what it is.
"""

from __future__ import annotations

import re

__all__ = ["KEYWORDS", "Fallback", "RuleMeta", "Word", "tokenize"]


class Fallback(Exception):
    """The fast path cannot vouch for this text: parse it with lark instead."""


_TOKEN = re.compile(
    r"(?P<ws>[ \t\f\r\n]+|//[^\n]*)"
    r"|(?P<D>[0-9]*\.[0-9]+(?:[eE][-+]?[0-9]+)?|[0-9]+[eE][-+]?[0-9]+)"
    r"|(?P<N>[0-9]+)"
    r"|(?P<I>[A-Za-z_][A-Za-z0-9_]*)"
    r'|(?P<S>"[^"\n]*")'
    r"|(?P<O><=>|=>|=\?|->|\.\.|\|\||<=|>=|!=|[-+*/^!&|=<>?:;,()\[\]{}'])"
)
#: Every keyword of prism.lark that is spelled like a name: as a name, it sends the
#: text to lark (whose contextual lexer decides per parser state).
KEYWORDS = frozenset({
    "dtmc", "probabilistic", "mdp", "nondeterministic", "ctmc", "stochastic", "pta", "ctmdp",
    "smg", "const", "int", "double", "bool", "rate", "prob", "formula", "label", "global",
    "module", "endmodule", "rewards", "endrewards", "init", "endinit", "true", "false", "func",
    "filter", "multi", "min", "max", "floor", "ceil", "pow", "mod", "log", "round",
    "P", "Pmin", "Pmax", "R", "Rmin", "Rmax", "S", "C", "I", "U", "W", "X", "F", "G", "A", "E",
})


class Word(str):
    """A token handed to a rule method (like lark's ``Token``, a ``str``)."""

    end_pos: int


class RuleMeta:
    """Where a rule starts (and, for a property, ends): what the rule methods read."""

    __slots__ = ("column", "end_pos", "line", "start_pos")

    def __init__(self, line: int, column: int, start_pos: int, end_pos: int) -> None:
        self.line, self.column = line, column
        self.start_pos, self.end_pos = start_pos, end_pos


def tokenize(text: str) -> tuple[list[str], list[str], list[int]]:
    """Kinds (``D N I S`` or the operator itself), texts and start offsets, then ``$``."""
    kinds: list[str] = []
    texts: list[str] = []
    starts: list[int] = []
    position = 0
    for match in _TOKEN.finditer(text):
        if match.start() != position:
            raise Fallback  # a character no token starts with: lark reports it
        position = match.end()
        kind = match.lastgroup
        if kind == "ws":
            continue
        value = match.group()
        kinds.append(value if kind == "O" else kind)  # type: ignore[arg-type]
        texts.append(value)
        starts.append(match.start())
    if position != len(text):
        raise Fallback
    kinds.append("$")
    texts.append("")
    starts.append(len(text))
    return kinds, texts, starts

