"""Expressions far deeper than Python's recursion limit: a 5,000-term disjunction and
conjunction, conditionals nested 5,000 deep (a chain and parenthesised), long sums.

Both parsers read them to the same nodes, and flattening, type checking, constant
evaluation and folding handle them without recursion, with PRISM's values (sums
folded left to right, ``&``/``|``/``? :`` short-circuiting). The model is checked
state by state in ``tests/explore/test_deep_expressions.py``.
"""

from __future__ import annotations

import dataclasses
import functools
import operator
import sys
from typing import Any

import pytest

from tests.lang.helpers import expression_depth, tree
from veribattery.errors import PrismSemanticError
from veribattery.lang import FlatModel, Ident, flatten_model, parse_model, parse_property
from veribattery.lang.evaluate import EvaluationError, evaluate
from veribattery.lang.expressions import walk
from veribattery.lang.fastparse import parse_fast
from veribattery.lang.parser import _parse_with_lark
from veribattery.lang.properties import resolve_property

#: Terms of each long disjunction, conjunction and sum; levels of each nested conditional.
TERMS = 5000
#: The counter's range 0..N: the even values below N are the disjunction's terms.
N = 2 * TERMS


def deep_model(terms: int = TERMS) -> str:
    """A counter ``x`` in 0..2*terms, its guards and rewards as long chains.

    From an even ``x < N`` it moves 1 or 2 up (probability 1/2 each), from an odd one
    1 up; ``x = N`` is absorbing. "even" is a *terms*-term disjunction, "odd" a
    *terms*-term conjunction, and each state's reward ``weight`` (2 at even ``x``,
    1 at odd) a conditional nested *terms* deep, as a chain and parenthesised.
    """
    n = 2 * terms
    even = " | ".join(f"x={i}" for i in range(0, n, 2))
    odd = " & ".join(f"x!={i}" for i in range(0, n, 2))
    chain = " ".join(f"x={i} ? {2 - i % 2} :" for i in range(terms))
    nested = " ".join(f"(x={i} ? {2 - i % 2} :" for i in range(terms))
    ones = " + ".join(["1"] * terms)
    tenths = " + ".join(["0.1"] * terms)
    deep = " ".join(f"(HALF={i} ? {i} :" for i in range(terms)) + " 7" + ")" * terms
    return f"""dtmc

const int N = {n};
const int HALF = {ones};
const double TENTHS = {tenths};
const int DEEP = {deep};

formula even = {even};
formula odd = {odd};
formula weight = {chain} mod(x+1, 2) + 1;
formula weight_nested = {nested} mod(x+1, 2) + 1{")" * terms};

module counter
  x : [0..N] init 0;
  [] x<N & even -> 0.5:(x'=x+1) + 0.5:(x'=x+2);
  [] x<N & odd -> (x'=x+1);
  [] x=N -> true;
endmodule

rewards "weight"
  x<N : weight;
endrewards

rewards "weight_nested"
  x<N : weight_nested;
endrewards

label "even" = even;
"""


@functools.cache
def _text() -> str:
    return deep_model()


@functools.cache
def _flat() -> FlatModel:
    return flatten_model(parse_model(_text()))


def _same_tree(a: Any, b: Any, *, spans: bool = True) -> bool:
    """Node equality, spans included unless *spans* is False, without recursion
    (``==`` and ``repr`` of nodes recurse)."""
    stack = [(a, b)]
    while stack:
        x, y = stack.pop()
        if type(x) is not type(y):
            return False
        if isinstance(x, tuple):
            if len(x) != len(y):
                return False
            stack.extend(zip(x, y, strict=True))
        elif dataclasses.is_dataclass(x):
            stack.extend((getattr(x, f.name), getattr(y, f.name))
                         for f in dataclasses.fields(x) if spans or f.name != "span")
        elif x != y:
            return False
    return True



def test_the_model_is_deeper_than_the_recursion_limit() -> None:
    model = parse_model(_text())
    formulas = {f.name: f.expr for f in model.formulas}
    for name in ("even", "odd", "weight", "weight_nested"):
        assert expression_depth(formulas[name]) >= TERMS > sys.getrecursionlimit()


def test_the_fast_parser_reads_it_as_lark_does() -> None:
    """The fast path vouches for the text (no fallback), and lark, the grammar of
    record, reads the same nodes with the same spans (on 2,000 terms: lark takes
    a second per thousand)."""
    text = deep_model(2000)
    fast = parse_fast(text, "deep.prism", "start_model")
    lark = _parse_with_lark(text, "deep.prism", "start_model")
    assert _same_tree(fast, lark)


def test_a_chain_and_its_parenthesised_form_are_the_same_tree() -> None:
    formulas = {f.name: f.expr for f in parse_model(_text()).formulas}
    assert _same_tree(formulas["weight"], formulas["weight_nested"], spans=False)


def test_constants_fold_left_to_right() -> None:
    """5,000-term sums evaluate as PRISM folds them (left to right: the double sum is
    not reassociated), and the conditional nested 5,000 deep falls through to 7."""
    constants = dict(_flat().constants)
    assert constants["HALF"] == TERMS
    assert constants["TENTHS"] == functools.reduce(operator.add, [0.1] * TERMS)
    assert constants["TENTHS"] != 0.1 * TERMS  # the fold order matters, and is kept
    assert constants["DEEP"] == 7


def test_flattening_inlines_the_long_formulas() -> None:
    (module,) = _flat().modules
    guard = module.commands[0].guard
    names = {node.name for node in walk(guard) if isinstance(node, Ident)}
    assert names == {"x"}  # even, N inlined; N replaced by its value
    assert sum(1 for node in walk(guard) if type(node).__name__ == "IntLit") == TERMS + 1


def test_the_deep_formulas_evaluate_per_prism() -> None:
    formulas = {f.name: f.expr for f in _flat().formulas}
    for value in (*range(6), *range(TERMS - 3, TERMS + 3), *range(N - 6, N + 1)):
        got = {name: evaluate(expr, {"x": value}) for name, expr in formulas.items()}
        even = value % 2 == 0 and value < N
        weight = 2 - value % 2
        assert got == {"even": even, "odd": not even, "weight": weight, "weight_nested": weight}


def test_evaluation_short_circuits_deep_in_a_chain() -> None:
    """``mod(1, Z)`` with Z = 0 has no value: never evaluated after a decided ``|``,
    ``&`` or a condition that picks the other branch, however deep."""
    fine = " | ".join(["Z=0", *["mod(1, Z)=0"] * TERMS])
    also = " & ".join(["Z!=0", *["mod(1, Z)=0"] * TERMS])
    branch = " ".join(["Z=0 ? 1 :"] * TERMS) + " mod(1, Z)"
    text = f"""dtmc
const int Z = 0;
const bool FINE = {fine};
const bool ALSO = {also};
const int BRANCH = {branch};
const int BAD = {" + ".join(["1"] * TERMS)} + mod(1, Z);
module m x : [0..1] init 0; endmodule
"""
    model = parse_model(text)
    with pytest.raises(EvaluationError, match="mod"):
        flatten_model(model)
    good = dataclasses.replace(model, constants=model.constants[:-1])
    constants = dict(flatten_model(good).constants)
    assert (constants["FINE"], constants["ALSO"], constants["BRANCH"]) == (True, False, 1)


def test_a_type_error_deep_in_a_chain_is_reported() -> None:
    terms = [f"x={i}" for i in range(TERMS)]
    terms[4000] = "x+1"
    text = f"dtmc\nmodule m\n  x : [0..1] init 0;\n  [] {' | '.join(terms)} -> true;\nendmodule\n"
    with pytest.raises(PrismSemanticError, match=r"'\|' cannot be applied to bool and int") as err:
        flatten_model(parse_model(text, name="bad.prism"))
    assert str(err.value).startswith("bad.prism:4:")


def test_a_deep_property_resolves_against_the_model() -> None:
    """A property's long state formula is inlined and type-checked like the model's."""
    far = " | ".join(f"x={i}" for i in range(N - TERMS, N))
    prop = parse_property(f'P=? [ F ("even" & ({far})) ]')
    resolved = resolve_property(prop, _flat())
    assert {n.name for n in walk(resolved.formula) if isinstance(n, Ident)} == {"x"}


@pytest.mark.parametrize(
    "text",
    [
        "x=0 ? 1 : (x=1 ? 2 : 3)",
        "x=0 ? 1 : (x=1 ? 2 : (x=2 ? 3 : 4))",
        "x=0 ? 1 : (x=1 ? 2 : 3) * 2",  # the group does not end the expression
        "x=0 ? 1 : (x) + 1",
        "x=0 ? 1 : (x)",
        "x=0 ? 1 : ((x=1 ? 2 : 3))",
        "(x=0 ? 1 : (x=1 ? 2 : 3)) + 1",
        "x=0 ? (x=1 ? 2 : 3) : (x=2 ? 4 : (x=3 ? 5 : 6))",
        'P=? [ F (x=0 ? true : (x=1 U x=2)) ]',  # a group that is no chain: read as usual
        'P=? [ F x=0 ? true : (x=1 ? false : (x=2)) ]',
        'P=? [ (x=0 ? true : (x=1)) U x=2 ]',
    ],
)
def test_parenthesised_last_branches_read_as_lark_reads_them(text: str) -> None:
    fast = tree(parse_fast(text, "p", "start_property"))
    assert fast == tree(_parse_with_lark(text, "p", "start_property"))


def chained_definitions(count: int = TERMS) -> str:
    """Constants and formulas each defined by the next one down, declared from the top
    (so evaluating the first needs all the others first): chains *count* long."""
    consts = "\n".join(f"const int c{i} = c{i - 1} + 1;" for i in reversed(range(1, count)))
    forms = "\n".join(f"formula f{i} = f{i - 1} + 1;" for i in reversed(range(1, count)))
    return f"""dtmc
{consts}
const int c0 = 0;
{forms}
formula f0 = x;
module m
  x : [0..1] init 0;
  [] x=0 -> (x'=min(1, f{count - 1} - c{count - 1} + 1));
  [] x=1 -> true;
endmodule
"""


def test_chains_of_constants_and_formulas_are_evaluated_and_inlined() -> None:
    flat = flatten_model(parse_model(chained_definitions()))
    assert dict(flat.constants)[f"c{TERMS - 1}"] == TERMS - 1
    (module,) = flat.modules
    (assignment,) = module.commands[0].updates[0].assignments
    assert evaluate(assignment.expr, {"x": 0}) == 1  # min(1, (x + 4999) - 4999 + 1)


def test_a_cycle_through_a_long_chain_is_named() -> None:
    text = chained_definitions(3000).replace("formula f0 = x;", "formula f0 = f2999;")
    with pytest.raises(PrismSemanticError, match=r"cyclic formula definition: f2999 -> f2998"):
        flatten_model(parse_model(text))
    text = chained_definitions(3000).replace("const int c0 = 0;", "const int c0 = c2999;")
    with pytest.raises(PrismSemanticError, match="constant 'c2999' is defined in terms of itself"):
        flatten_model(parse_model(text))
