"""Building and checking models whose expressions are far deeper than Python's
recursion limit, and the compiled chains that evaluate them in a loop.

The counter of ``tests/lang/test_deep_expressions.py`` (x in 0..10,000, guards and
labels that are 5,000-term disjunctions and conjunctions, state rewards that are
conditionals nested 5,000 deep) has hand-checked counts and values: every x is
reachable (10,001 states); an even x < N has two transitions, an odd one one, N a
self-loop (5,000 * 2 + 5,000 + 1 = 15,001); from an even x the reward to reach N
is R(x) = 2 + (R(x+1) + R(x+2))/2 = 2.5 + R(x+2), so R(0) = 2.5 * 5,000 = 12,500.
"""

from __future__ import annotations

import functools
import operator
import random

import numpy as np
import pytest

from tests.lang.test_deep_expressions import TERMS, N, chained_definitions, deep_model
from veribattery.errors import ModelError
from veribattery.explore import compile_expr
from veribattery.explore.compile import operators as operators_module
from veribattery.explore.compile.bounds import value_bounds
from veribattery.explore.compile.expr import CompileCache, variables_of
from veribattery.explore.exact.program import needs_exact
from veribattery.explore.exact.rational import evaluate_rational, rational
from veribattery.lang import parse_model
from veribattery.lang.nodes import Expr
from veribattery.lang.parser import parse_properties
from veribattery.pipeline import ModelCheckRun, check_model, check_model_exact

PROPERTIES = """
P=? [ F x=N ];
R{"weight"}=? [ F x=N ];
R{"weight_nested"}=? [ F x=N ];
P=? [ F "even" & x>=N-2 ];
"""


@functools.cache
def _run() -> ModelCheckRun:
    model = parse_model(deep_model())
    props = parse_properties(PROPERTIES)
    return check_model(model, props.properties, props_file=props)


def test_the_counter_has_the_hand_checked_size() -> None:
    dtmc = _run().dtmc
    assert (dtmc.num_states, dtmc.num_transitions, len(dtmc.initial)) == (N + 1, 15_001, 1)
    x = np.asarray(dtmc.states[:, 0])
    assert sorted(x.tolist()) == list(range(N + 1))
    np.testing.assert_array_equal(dtmc.labels["even"], (x % 2 == 0) & (x < N))
    assert int(np.count_nonzero(dtmc.labels["even"])) == TERMS


def test_deep_rewards_are_each_states_weight() -> None:
    dtmc = _run().dtmc
    x = np.asarray(dtmc.states[:, 0])
    expected = np.where(x < N, 2 - x % 2, 0).astype(np.float64)
    for name in ("weight", "weight_nested"):
        (vectors,) = [r for r in dtmc.rewards if r.name == name]
        np.testing.assert_array_equal(vectors.state, expected)


def test_the_counter_checks_to_the_hand_computed_values() -> None:
    values = [r.value for r in _run().results]
    assert values[0] == 1.0
    assert values[1] == pytest.approx(2.5 * TERMS, rel=1e-9)
    assert values[2] == pytest.approx(2.5 * TERMS, rel=1e-9)
    assert values[3] == 1.0  # N-2 is even and visited with probability 1


def test_the_exact_path_evaluates_deep_expressions_as_rationals() -> None:
    """Guards decided exactly, rewards as rationals, on 1,500 terms (the exact
    solver is slower; 1,500 nested calls would still exceed the recursion limit):
    2.5 * 1,500 exactly."""
    model = parse_model(deep_model(1500))
    props = parse_properties('R{"weight"}=? [ F x=N ]; R{"weight_nested"}=? [ F x=N ];')
    run = check_model_exact(model, props.properties, props_file=props)
    assert (run.dtmc.num_states, run.dtmc.num_transitions) == (3001, 4501)
    assert [str(getattr(r, "exact", None)) for r in run.results] == ["3750", "3750"]


# ---------------------------------------------------------------------------
# Compiled chains: nested calls below SPINE_LIMIT links, a loop from there on
# ---------------------------------------------------------------------------

NAMES = ("x", "y", "z")


def _rows(count: int = 3000, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.stack([rng.integers(-50, 50, count), rng.integers(0, 6, count),
                     rng.integers(0, 2, count)], axis=1).astype(np.int64)


def _parsed(text: str) -> Expr:
    model = parse_model(f"dtmc\nformula f = {text};\nmodule m x:[0..1]; endmodule\n")
    return model.formulas[0].expr


def _long_chains(rng: random.Random, links: int, shape: int) -> str:
    """A chain of *links* links of one of seven shapes, with operands that are risky
    (division), long (skipped ``&``/``|``) or plain."""
    leaf = ["x", "y", "z=1", "x/(y+1)", "y>0 & x/y>1", "x*y-3", "2.5", "-x", "min(x, y)"]
    numbers = ["x", "y", "x/(y+1)", "x*y-3", "2.5", "-x", "min(x, y)", "mod(x, y+1)"]
    if shape == 0:  # left-nested arithmetic
        return " ".join(["x", *(f"{rng.choice('+-*')} {rng.choice(numbers)}"
                                for _ in range(links))])
    if shape == 1:  # left-nested connectives, some operands long or risky
        terms = [f"({rng.choice([leaf[4], f'x>{i}', f'y={i % 6} & z=1 & x>0'])})"
                 if rng.random() < 0.5 else f"x={i - 40}" for i in range(links)]
        return rng.choice([" | ", " & "]).join(terms)
    if shape in (2, 6):  # right-nested connectives, with risky or long operands
        op = rng.choice(["|", "&"])
        side = "y>0 & x/y>{}" if shape == 2 else "y={} & z=1 & x>0"
        return "".join(f"(x={i - 40} {op} ({side.format(i % 6)}) {op} "
                       for i in range(links)) + "z=1" + ")" * links
    if shape == 3:  # conditionals nested in the last branch, risky values
        return " ".join(f"x={i - 40} ? {rng.choice(numbers)} :" for i in range(links)) + " y"
    if shape == 4:  # conditionals nested in the first branch
        return "".join(f"(x>{40 - i} ? " for i in range(links)) + "x" + "".join(
            f" : {rng.choice(numbers)})" for _ in range(links))
    return " + ".join(f"(x={i - 40} ? 1 : {i % 3})" for i in range(links))  # sum of ites


@pytest.mark.parametrize("seed", range(28))
def test_a_chain_in_a_loop_equals_its_nested_calls(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every linked node unrolled (SPINE_LIMIT 1) gives the values of the nested calls
    (SPINE_LIMIT as shipped, the chain short): same dtype, same bits, same error."""
    rng = random.Random(seed)
    text = _long_chains(rng, rng.randrange(2, 30), seed % 7)
    rows = _rows(seed=seed)
    found = []
    for limit in (operators_module.SPINE_LIMIT, 1):
        monkeypatch.setattr(operators_module, "SPINE_LIMIT", limit)
        fn = compile_expr(_parsed(text), NAMES)
        try:
            found.append(fn(rows))
        except ModelError as error:
            found.append(error)
    nested, looped = found
    if isinstance(nested, ModelError):
        assert str(looped) == str(nested), text
        return
    assert isinstance(looped, np.ndarray), text
    assert looped.dtype == nested.dtype, text
    assert looped.tobytes() == nested.tobytes(), text


@pytest.mark.parametrize("ranges", [None, {"x": (-50, 49), "y": (0, 5), "z": (0, 1)}])
def test_chains_of_five_thousand_links_evaluate(ranges: dict[str, tuple[int, int]] | None) -> None:
    """Without tables (no ranges) the chains run in a loop; with them, as lookups."""
    rows = _rows()
    x, y, z = rows[:, 0], rows[:, 1], rows[:, 2]
    cases = {
        " | ".join(f"x={i}" for i in range(-2500, 2500)): np.ones(len(x), bool),
        " & ".join(f"x!={i}" for i in range(0, 2 * TERMS, 2)): (x < 0) | (x % 2 == 1),
        "".join(f"(x={i} | " for i in range(TERMS)) + "false" + ")" * TERMS: x >= 0,
        " ".join(f"x={i} ? {i} :" for i in range(-TERMS // 2, TERMS // 2)) + " 0": x,
        " + ".join(["x"] * TERMS): TERMS * x,
        " - ".join(["y"] * TERMS): y - (TERMS - 1) * y,
        " ".join(f"y={i % 6} & z=1 ? x/(y+1) :" for i in range(TERMS)) + " x": np.where(
            z == 1, x / (y + 1), x),
    }
    cache = CompileCache() if ranges is not None else None
    for text, expected in cases.items():
        got = compile_expr(_parsed(text), NAMES, ranges=ranges, cache=cache)(rows)
        np.testing.assert_array_equal(got, expected, err_msg=text[:60])


def test_a_long_double_sum_keeps_its_order() -> None:
    """``0.1 + 0.1 + ...`` with a variable term: folded and evaluated left to right."""
    text = " + ".join(["0.1"] * 3000 + ["x"] + ["0.1"] * 2000)
    rows = _rows()
    got = compile_expr(_parsed(text), NAMES)(rows)
    head = functools.reduce(operator.add, [0.1] * 3000)
    expected = functools.reduce(operator.add, [0.1] * 2000, head + rows[:, 0])
    assert got.tobytes() == expected.tobytes()


def test_static_analyses_of_deep_expressions() -> None:
    chain = _parsed(" + ".join(["x"] * TERMS))
    assert value_bounds(chain, {"x": (0.0, 2.0)}) == (0.0, 2.0 * TERMS)
    assert variables_of(chain) == {"x"}
    assert not needs_exact(chain)
    assert needs_exact(_parsed(" + ".join(["x"] * TERMS + ["0.5"])))
    ites = _parsed(" ".join(f"x={i} ? {i} :" for i in range(TERMS)) + " y")
    assert value_bounds(ites, {"x": (0.0, 1.0), "y": (-3.0, 0.0)}) == (-3.0, TERMS - 1.0)


def test_exact_values_of_deep_expressions() -> None:
    tenths = evaluate_rational(_parsed(" + ".join(["0.1"] * TERMS)), {}, {}, 1)
    assert tenths[0] == rational(TERMS // 10)
    column = np.array([rational(v) for v in range(-3, 4)], dtype=object)
    guarded = _parsed(" ".join(f"x={i} ? 1/x :" for i in range(1, TERMS)) + " 0")
    values = evaluate_rational(guarded, {}, {"x": column}, 7)  # no 1/0 where x = 0
    assert [str(v) for v in values] == ["0", "0", "0", "0", "1", "1/2", "1/3"]


def test_exact_constants_of_long_chains() -> None:
    """The exact path recomputes a 5,000-long chain of constants as rationals."""
    model = parse_model(chained_definitions())
    props = parse_properties("P=? [ F x=1 ];")
    run = check_model_exact(model, props.properties, props_file=props)
    assert [str(getattr(r, "exact", None)) for r in run.results] == ["1"]
