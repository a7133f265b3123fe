"""Properties whose state formulas are far deeper than Python's recursion limit.

The walk: x in 0..3,000, each step up with probability 1/2, else stay; 3,000 absorbs.
Every state reaches 3,000 with probability 1, so ``P>=1 [ F x=3000 ]`` holds
everywhere, and a chain of 3,000 disjuncts ``x=1 | ... | x=3000`` holds exactly in
the states 1..3,000: ``P=? [ F chain ]`` is 1 from 0, and so are the same chains with
a bounded operator inside, first or last.
"""

from __future__ import annotations

from fractions import Fraction

import pytest

from tests.checker.test_exact import exact_run
from veribattery.checker import check
from veribattery.explore import build_dtmc
from veribattery.lang import flatten_model, parse_model, parse_property

TOP = 3_000
WALK = (f"dtmc\nmodule m\n  x : [0..{TOP}] init 0;\n"
        f"  [] x<{TOP} -> 0.5:(x'=x+1) + 0.5:(x'=x);\n  [] x={TOP} -> true;\nendmodule\n")
CHAIN = " | ".join(f"x={i}" for i in range(1, TOP + 1))
NOT_ZERO = " & ".join(f"x!={i}" for i in range(TOP + 1, 2 * TOP))  # true everywhere
PROPERTIES = [
    f"P=? [ F {CHAIN} ]",
    f"P=? [ F P>=1 [ F x={TOP} ] & ({CHAIN}) ]",
    f"P=? [ F ({CHAIN}) | P>=1 [ F x=5 ] ]",
    f"P=? [ F ({NOT_ZERO}) & x={TOP} ]",
]


@pytest.fixture(scope="module")
def walk():  # type: ignore[no-untyped-def]
    return build_dtmc(flatten_model(parse_model(WALK)))


@pytest.mark.parametrize("text", PROPERTIES, ids=["chain", "operator-first", "operator-last",
                                                  "conjunction"])
def test_a_3000_term_state_formula_is_checked(walk, text: str) -> None:  # type: ignore[no-untyped-def]
    assert check(walk, parse_property(text)).value == pytest.approx(1.0, abs=1e-9)


def test_and_exactly() -> None:
    first, second = exact_run(WALK, *PROPERTIES[:2])
    assert first.exact == second.exact == Fraction(1)


def test_the_chain_holds_where_it_should(walk) -> None:  # type: ignore[no-untyped-def]
    result = check(walk, parse_property(f"filter(count, {CHAIN})"))
    assert result.value == TOP
