"""Lookup tables of compiled expressions: narrowed storage, failure marks, and that a
tabulated expression equals its row-wise evaluation on every valuation of its domain."""

from __future__ import annotations

import itertools
import random

import numpy as np
import pytest

from tests.explore.models import expr
from tests.explore.test_fused import _assert_same_exploration
from veribattery.errors import ModelError
from veribattery.explore import compile_expr
from veribattery.explore.build.builder import explore
from veribattery.explore.build.plan import plan_layers
from veribattery.explore.compile.expr import CompileCache, may_fail
from veribattery.explore.compile.program import compile_program
from veribattery.explore.compile.tables import narrowed
from veribattery.lang.parser import parse_model
from veribattery.lang.semantics import flatten_model

NAMES = ("x", "y", "z")
RANGES = {"x": (-3, 4), "y": (0, 5), "z": (0, 1)}


def _domain() -> np.ndarray:
    grids = np.meshgrid(*(np.arange(lo, hi + 1) for lo, hi in RANGES.values()), indexing="ij")
    return np.stack([g.ravel() for g in grids], axis=1).astype(np.int64)


def _both(text: str) -> tuple[object, object]:
    """(row-wise result or error, tabulated result or error) on the whole domain."""
    states = _domain()
    found = []
    for ranges in (None, RANGES):
        fn = compile_expr(expr(text), NAMES, ranges=ranges, cache=CompileCache())
        try:
            found.append(fn(states))
        except ModelError as error:
            found.append(error)
    return found[0], found[1]


_LEAVES = ["x", "y", "z", "1", "2", "3", "0", "-2", "0.5", "2.25"]
_BINARY = ["+", "-", "*", "/", "<", "<=", "=", "!=", ">", ">="]


def _random_expr(rng: random.Random, depth: int) -> str:
    if depth == 0 or rng.random() < 0.2:
        return rng.choice(_LEAVES)
    a, b = _random_expr(rng, depth - 1), _random_expr(rng, depth - 1)
    pick = rng.randrange(8)
    if pick < 3:
        return f"({a} {rng.choice(_BINARY)} {b})"
    if pick == 3:
        return f"({_random_expr(rng, depth - 1)} > {a} ? {b} : {a})"
    if pick == 4:
        return f"{rng.choice(['min', 'max'])}({a}, {b})"
    if pick == 5:
        return f"{rng.choice(['floor', 'ceil'])}({a})"
    if pick == 6:  # integer arguments: mod and pow may fail on some valuations only
        first, second = rng.choice(["x", "y", "7"]), rng.choice(["x", "y", "2"])
        return f"{rng.choice(['mod', 'pow'])}({first}, {second})"
    return f"(({a} > {b}) & ({b} != 0) | z = 1)"


@pytest.mark.parametrize("seed", range(40))
def test_tabulated_equals_row_wise_on_random_expressions(seed: int) -> None:
    """Same values and type on every valuation, or the same error (floor of a division
    by zero, mod and pow of bad arguments included)."""
    text = _random_expr(random.Random(seed), 4)
    plain, table = _both(text)
    if isinstance(plain, ModelError):
        assert isinstance(table, ModelError), text
        assert str(table) == str(plain), text
        return
    assert isinstance(table, np.ndarray) and isinstance(plain, np.ndarray), text
    assert table.dtype == plain.dtype, text
    assert table.tobytes() == plain.tobytes(), text  # bit for bit, NaN and -0.0 included


def test_narrow_tables_give_wide_values() -> None:
    """A table of small integers is stored in one byte, but lookups give int64, so
    arithmetic on them cannot wrap: 100 * (x+120) reaches 12400 > 127."""
    fn = compile_expr(expr("100 * (x = 0 ? 124 : (x + 120))"), NAMES, ranges=RANGES,
                      cache=CompileCache())
    states = _domain()
    got = fn(states)
    assert got.dtype == np.int64
    x = states[:, 0]
    np.testing.assert_array_equal(got, 100 * np.where(x == 0, 124, x + 120))


@pytest.mark.parametrize(
    ("values", "dtype"),
    [
        ([0, 127, -128], np.int8),
        ([0, 128], np.int16),
        ([-40000, 1], np.int32),
        ([0, 1 << 40], np.int64),
        ([0.5, -0.0, 3.0], np.float32),
        ([0.1, 1.0], np.float64),  # 0.1 is not a float32
        ([float("nan"), 1.0], np.float64),  # not provably exact: kept
        ([True, False], np.bool_),
    ],
)
def test_narrowed_type_holds_every_value_exactly(values: list[object], dtype: type) -> None:
    table = np.array(values)
    narrow = narrowed(table)
    assert narrow.dtype == dtype
    assert narrow.astype(table.dtype).tobytes() == table.tobytes()


def test_may_fail_marks_only_row_dependent_failures() -> None:
    cache = CompileCache()

    def compiled(text: str, ranges: dict[str, tuple[int, int]] | None = RANGES) -> object:
        return compile_expr(expr(text), NAMES, ranges=ranges, cache=cache)

    # A division tabulated without error cannot fail on a state within the ranges.
    assert not may_fail(compiled("floor(10 * (y + 1) / 7) + x"))  # type: ignore[arg-type]
    # Not tabulated (no ranges): it is evaluated row-wise and marked.
    assert may_fail(compiled("floor(10 * (y + 1) / 7) + x", None))  # type: ignore[arg-type]
    # Fails at y = 0 (floor(10/0) has no int): not tabulated, so evaluated only on
    # the rows that need it.
    failing = compiled("floor(10 / y) + x")
    assert may_fail(failing)  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="cannot take floor of inf"):
        failing(_domain())  # type: ignore[operator]
    # 10/y alone has a value everywhere (infinite at y = 0): tabulated, cannot fail.
    assert not may_fail(compiled("10 / y + x"))  # type: ignore[arg-type]
    assert not may_fail(compiled("x + y * 2"))  # type: ignore[arg-type]


_RISKY_UPDATES = """dtmc
module m
  x : [0..6] init 0;
  y : [0..3] init 3;
  [] x<6 -> (y+1)/5:(x'=floor(6*(x+1)/7)) & (y'=y=0?0:y-1) + 1-(y+1)/5:(x'=x+1);
  [] y>0 -> (x'=min(6, floor(6/y)));
  [] x=6 -> (x'=0) & (y'=3);
endmodule
"""


def test_fused_layers_with_tabulated_and_failing_divisions() -> None:
    """A division tabulated without error is evaluated on the whole frontier, one that
    fails where its command is disabled (6/y at y=0) only where it is enabled: both
    give the group-by-group path's layers, bit for bit, and no error."""
    model = flatten_model(parse_model(_RISKY_UPDATES), {})
    plan = plan_layers(compile_program(model))
    assert plan is not None
    # floor(6*(x+1)/7), y=0?0:y-1 and x+1 are not risky; min(6, floor(6/y)) is
    assert sorted(e.risky for e in plan.values.exprs) == [False, False, False, True]
    assert [e.risky for e in plan.factors.exprs] == [False, False]
    _assert_same_exploration(model)
    # ... and the fused path itself expanded every layer (no fall-back)
    states, _, layers = explore(model, compile_program(model))
    starts = [int(layer.rows[0]) for layer in layers] + [states.shape[0]]
    for low, high in itertools.pairwise(starts):
        assert plan.expand(states[low:high], set()) is not None


def test_a_chain_over_one_variable_is_one_table_not_one_per_level() -> None:
    """A route's ``k=0 ? 4 : k=1 ? 3 : ...`` is tabulated from the top: its sub-chains,
    over the same variable, get no tables of their own (a 250 x 250 farm's formulas held
    one table over the whole route per level: 9 GB), and the values are the row-wise
    ones on every valuation."""
    levels = 300
    values = [(7 * level) % 11 for level in range(levels)]
    text = " : ".join(f"k={level} ? {value}" for level, value in enumerate(values)) + " : -1"
    cache = CompileCache()
    fn = compile_expr(expr(text), ("k",), ranges={"k": (0, levels)}, cache=cache)
    states = np.arange(levels + 1, dtype=np.int64)[:, None]
    np.testing.assert_array_equal(fn(states), [*values, -1])
    assert len(cache.nodes) == 1  # the chain's own table; its levels are row-wise nodes
    row_wise = compile_expr(expr(text), ("k",), cache=CompileCache())
    assert row_wise(states).tobytes() == fn(states).tobytes()
