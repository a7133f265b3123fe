"""The fast path of the parser: a regex tokenizer and a precedence-climbing parser.

``prism.lark`` stays the grammar of record. This module accepts the part of it that
real models use and builds the same nodes through the same rule methods
(:class:`~veribattery.lang.transform.ToNodes`), with the same spans: a node's span
is where its rule's first token is, parentheses being no rule of their own. Anything
else -- a syntax error, a semantic error raised by a rule, a keyword spelled where a
name is expected, ``R`` as the release operator -- raises
:class:`Fallback`, and the facade re-parses the text with lark, which then produces
the result or the error message. Equality with lark is tested on every model and
properties file in the repository and the peer suites, and on generated expressions.

Why not lark alone: LALR through the 15-level precedence chain costs a reduction per
level per operand (and positions on each), 56 s for a 2 MB generated model; this
parser does one call per level actually used. It also spares a process that parses
well-formed text importing lark and loading its grammar.
"""

from __future__ import annotations

import gc
from typing import Any

from veribattery.errors import VeribatteryError
from veribattery.lang.fastexpr import ExprParser
from veribattery.lang.lexer import Fallback, Word

__all__ = ["Fallback", "parse_fast"]

_MODEL_TYPES = frozenset(
    {"dtmc", "probabilistic", "mdp", "nondeterministic", "ctmc", "stochastic", "pta", "ctmdp",
     "smg"}
)
_CONST_TYPES = frozenset({"int", "double", "bool", "rate", "prob"})


class _FileParser(ExprParser):
    """Model and properties files: declarations, modules, commands, rewards, properties."""


    def model(self) -> Any:
        items = []
        while self.kinds[self.i] != "$":
            items.append(self.model_item())
        return self.rules.start_model(self.meta(0), items)

    def model_item(self) -> Any:
        if self.kinds[self.i] != "I":
            raise Fallback
        word = self.texts[self.i]
        if word in _MODEL_TYPES:
            start = self.i
            return self.rules.model_type(self.meta(start), [self.word()])
        handler = _MODEL_ITEMS.get(word)
        if handler is None:
            raise Fallback
        return handler(self)

    def const_decl(self) -> Any:
        start = self.i
        self.i += 1
        children: list[Any] = []
        if self.at_word(*_CONST_TYPES):
            type_start = self.i
            children.append(self.rules.const_type(self.meta(type_start), [self.word()]))
        children.append(self.name())
        if self.kinds[self.i] == "=":
            self.i += 1
            children.append(self.expr())
        self.expect(";")
        return self.rules.const_decl(self.meta(start), children)

    def formula_decl(self) -> Any:
        start = self.i
        self.i += 1
        name = self.name()
        self.expect("=")
        value = self.expr()
        self.expect(";")
        return self.rules.formula_decl(self.meta(start), [name, value])

    def label_decl(self) -> Any:
        start = self.i
        self.i += 1
        name = self.string()
        self.expect("=")
        value = self.expr()
        self.expect(";")
        return self.rules.label_decl(self.meta(start), [name, value])

    def global_decl(self) -> Any:
        start = self.i
        self.i += 1
        return self.rules.global_decl(self.meta(start), [self.var_decl()])

    def var_decl(self) -> Any:
        start = self.i
        name = self.name()
        self.expect(":")
        if self.at_word("bool"):
            self.i += 1
            children = [name, *self.var_init()]
            return self.rules.bool_var(self.meta(start), children)
        self.expect("[")
        low = self.expr()
        self.expect("..")
        high = self.expr()
        self.expect("]")
        children = [name, low, high, *self.var_init()]
        return self.rules.int_var(self.meta(start), children)

    def var_init(self) -> list[Any]:
        init = []
        if self.at_word("init"):
            start = self.i
            self.i += 1
            init.append(self.rules.var_init(self.meta(start), [self.expr()]))
        self.expect(";")
        return init

    def module(self) -> Any:
        start = self.i
        self.i += 1
        children: list[Any] = [self.name()]
        if self.kinds[self.i] == "=":
            return self.renamed_module(start, children[0])
        while not self.at_word("endmodule"):
            children.append(self.command() if self.kinds[self.i] == "[" else self.var_decl())
        self.i += 1
        return self.rules.module(self.meta(start), children)

    def renamed_module(self, start: int, name: Word) -> Any:
        self.i += 1
        children: list[Any] = [name, self.name()]
        self.expect("[")
        while True:
            rename_start = self.i
            pair: list[str] = [self.name()]
            self.expect("=")
            pair.append(self.name())
            children.append(self.rules.rename(self.meta(rename_start), pair))
            if self.kinds[self.i] != ",":
                break
            self.i += 1
        self.expect("]")
        self.expect_word("endmodule")
        return self.rules.renamed_module(self.meta(start), children)

    def action(self) -> list[Any]:
        """``[ name? ]`` of a command or transition reward."""
        self.expect("[")
        action = [] if self.kinds[self.i] == "]" else [self.name()]
        self.expect("]")
        return action

    def command(self) -> Any:
        start = self.i
        children = self.action()
        children.append(self.expr())
        self.expect("->")
        children.append(self.updates())
        self.expect(";")
        return self.rules.command(self.meta(start), children)

    def updates(self) -> Any:
        start, kinds = self.i, self.kinds
        plain_true = self.at_word("true") and kinds[start + 1] == ";"
        if plain_true or (kinds[start] == "(" and kinds[start + 2] == "'"):
            return self.rules.plain_update(self.meta(start), [self.update_body()])
        branches = [self.prob_update()]
        while kinds[self.i] == "+":
            self.i += 1
            branches.append(self.prob_update())
        return self.rules.updates(self.meta(start), branches)

    def prob_update(self) -> Any:
        start = self.i
        probability = self.expr()
        self.expect(":")
        return self.rules.prob_update(self.meta(start), [probability, self.update_body()])

    def update_body(self) -> Any:
        start = self.i
        if self.at_word("true"):
            self.i += 1
            return self.rules.true_update(self.meta(start), [])
        assignments = [self.assignment()]
        while self.kinds[self.i] == "&":
            self.i += 1
            assignments.append(self.assignment())
        return self.rules.assignments(self.meta(start), assignments)

    def assignment(self) -> Any:
        start = self.i
        self.expect("(")
        name = self.name()
        self.expect("'")
        self.expect("=")
        value = self.expr()
        self.expect(")")
        return self.rules.assignment(self.meta(start), [name, value])

    def rewards(self) -> Any:
        start = self.i
        self.i += 1
        children: list[Any] = [self.string()] if self.kinds[self.i] == "S" else []
        while not self.at_word("endrewards"):
            children.append(self.reward_item())
        self.i += 1
        return self.rules.rewards(self.meta(start), children)

    def reward_item(self) -> Any:
        start = self.i
        transition = self.kinds[start] == "["
        children = self.action() if transition else []
        children.append(self.expr())
        self.expect(":")
        children.append(self.expr())
        self.expect(";")
        rule = self.rules.transition_reward if transition else self.rules.state_reward
        return rule(self.meta(start), children)

    def init_block(self) -> Any:
        start = self.i
        self.i += 1
        value = self.expr()
        self.expect_word("endinit")
        return self.rules.init_block(self.meta(start), [value])

    # --------------------------------------------------------- properties file

    def properties(self) -> Any:
        items = []
        while self.kinds[self.i] != "$":
            if self.kinds[self.i] == ";":
                self.i += 1
            elif self.at_word("const"):
                items.append(self.const_decl())
            elif self.at_word("label"):
                items.append(self.label_decl())
            else:
                items.append(self.property())
        return self.rules.start_props(self.meta(0), items)

    def property(self) -> Any:
        start = self.i
        children: list[Any] = []
        if self.kinds[start] == "S" and self.kinds[start + 1] == ":":
            children.append(self.word())
            self.i += 1
        children.append(self.expr())
        return self.rules.property(self.meta(start), children)

    def single_property(self) -> Any:
        while self.kinds[self.i] == ";":
            self.i += 1
        prop = self.property()
        while self.kinds[self.i] == ";":
            self.i += 1
        if self.kinds[self.i] != "$":
            raise Fallback
        return self.rules.start_property(self.meta(0), [prop])


_MODEL_ITEMS = {
    "const": _FileParser.const_decl,
    "formula": _FileParser.formula_decl,
    "label": _FileParser.label_decl,
    "global": _FileParser.global_decl,
    "module": _FileParser.module,
    "rewards": _FileParser.rewards,
    "init": _FileParser.init_block,
}
_STARTS = {
    "start_model": _FileParser.model,
    "start_props": _FileParser.properties,
    "start_property": _FileParser.single_property,
}


def parse_fast(text: str, source: str, start: str) -> Any:
    """Parse *text* from grammar rule *start* as lark would, or raise :class:`Fallback`.

    :raises Fallback: on anything this parser does not vouch for, errors included
    """
    collecting = gc.isenabled()
    gc.disable()  # a large model is a million young objects that all survive: no cycles
    try:
        parser = _FileParser(text, source)
        if parser.kinds[0] == "$" and start == "start_property":
            raise Fallback
        return _STARTS[start](parser)
    except (VeribatteryError, IndexError, RecursionError) as exc:
        raise Fallback from exc
    finally:
        if collecting:
            gc.enable()

