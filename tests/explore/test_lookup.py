"""Narrow layers look their guards and right-hand sides up in tables (``build.lookup``).

The chain below is deep and narrow (N + 1 layers of one or two states), so every
layer takes the lookup path. By hand: from x=0 each step raises x by one and sets
b true with probability p, so the states are x=0 (b false) and x=1..N with either b:
2N + 1 states. Below N the tick (x a multiple of w=1) is a second choice, a
self-loop, so a state has three successors, each choice weighted 1/2; at x=N
nothing is enabled (two deadlocks, self-looped). x reaches N surely, and its last
step sets b with probability p: P(F x=N & b) = p. The first guard spans
401*101*4*2 > 2**16 valuations and is tabulated by conjuncts; the tick's is not
tabulated at all (``mod(x, w)`` fails at w=0) and is evaluated as before.
``mod(x, w)`` as a right-hand side is risky and evaluated where its command is
enabled; ``x+1`` and ``mod(x+1, w+2)`` are looked up.
"""

from __future__ import annotations

import numpy as np
import pytest

from veribattery.checker import check
from veribattery.explore import build_dtmc
from veribattery.explore.build import lookup as lookup_module
from veribattery.explore.build.lookup import LookupBuilder, conjuncts
from veribattery.explore.build.plan import plan_layers
from veribattery.explore.compile.program import compile_program
from veribattery.lang import parse_property
from veribattery.lang.nodes import Binary, FlatModel
from veribattery.lang.parser import parse_model
from veribattery.lang.semantics import flatten_model

N = 400

CHAIN = f"""dtmc
const int N = {N};
const double p = 0.3;
module chain
  x : [0..N] init 0;
  b : bool init false;
  z : [0..100] init 0;
  w : [0..3] init 1;
  y : [0..3] init 0;
  v : [0..7] init 0;
  [] x<N & z>=0 & w>=1 & b=b -> p : (x'=x+1) & (b'=true) & (y'=mod(x+1, w+2))
                                + 1-p : (x'=x+1) & (b'=false) & (y'=mod(x+1, w+2));
  [tick] mod(x, w)=0 & x<N -> (v'=mod(x, w));
endmodule
module clock
  [tick] true -> true;
endmodule
label "top" = x=N & b;
"""


def _flat(text: str) -> FlatModel:
    return flatten_model(parse_model(text), {})


@pytest.fixture
def at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """Lookups from the first narrow layer on (not only after ``DEEP`` of them)."""
    monkeypatch.setattr(lookup_module, "DEEP", 0)


@pytest.mark.usefixtures("at_once")
def test_the_chain_has_its_hand_counted_states_and_value() -> None:
    dtmc = build_dtmc(_flat(CHAIN))
    assert dtmc.num_states == 2 * N + 1
    assert dtmc.num_transitions == 3 * (2 * N - 1) + 2
    assert dtmc.deadlocks == 2
    assert check(dtmc, parse_property('P=? [ F "top" ]')).value == pytest.approx(0.3, abs=1e-9)


@pytest.mark.parametrize("deep", [0, 100])
def test_the_lookup_path_builds_the_same_dtmc_as_evaluating(
    monkeypatch: pytest.MonkeyPatch, deep: int
) -> None:
    """Looked up from the first layer, or from the 101st (both paths in one search)."""
    monkeypatch.setattr(lookup_module, "DEEP", deep)
    looked_up = build_dtmc(_flat(CHAIN))
    monkeypatch.setattr(lookup_module, "NARROW", 0)  # no frontier is narrow: all evaluated
    evaluated = build_dtmc(_flat(CHAIN))
    assert np.array_equal(looked_up.states, evaluated.states)
    for part in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(looked_up.transitions, part),
                              getattr(evaluated.transitions, part))
    assert looked_up.labels.keys() == evaluated.labels.keys()
    for name, mask in looked_up.labels.items():
        assert np.array_equal(mask, evaluated.labels[name])


@pytest.mark.usefixtures("at_once")
def test_the_plan_tabulates_conjuncts_and_leaves_a_failing_guard() -> None:
    program = compile_program(_flat(CHAIN))
    plan = plan_layers(program)
    assert plan is not None and plan.narrow is not None
    assert plan.narrow.lookups(lookup_module.NARROW + 1) is None  # a wide frontier
    lookups = plan.narrow.lookups(1)
    assert lookups is not None and lookups.guards is not None
    residual = [c for part in lookups.guards.residual for c, _, _ in part]
    assert len(residual) == 1  # the tick's guard: mod(x, w) fails at w=0
    assert lookups.guards.kinds is None  # so the enabledness is combined part by part
    assert lookups.lookup.units == lookups.first_value + len(lookups.looked_up)
    left = [e for e in range(len(plan.values.exprs)) if e not in lookups.looked_up]
    assert [plan.values.exprs[e].risky for e in left] == [True]  # mod(x, w) only


def test_lookups_are_made_after_deep_narrow_layers(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(lookup_module, "DEEP", 3)
    plan = plan_layers(compile_program(_flat(CHAIN)))
    assert plan is not None and plan.narrow is not None
    found = [plan.narrow.lookups(n) for n in (1, 1000, 2, 3, 4)]
    assert [f is None for f in found] == [True, True, True, True, False]


def test_a_lookup_gives_the_expression_s_values() -> None:
    """The table of ``x*3 - y`` over x in [-2..5], y in [0..3], read at chosen rows."""
    flat = _flat("dtmc\nmodule m\n x : [-2..5] init 0;\n y : [0..3] init 0;\n"
                 "[] x*3-y>=0 -> (x'=x);\nendmodule\n")
    guard = flat.modules[0].commands[0].guard
    assert isinstance(guard, Binary)
    builder = LookupBuilder(("x", "y"), {"x": (-2, 5), "y": (0, 3)}, np.int64)
    unit = builder.add(guard.left)  # x*3 - y
    assert unit == 0
    lookup = builder.finish()
    rows = np.array([[-2, 0], [5, 3], [0, 1], [3, 2]], dtype=np.int64)
    assert lookup.evaluate(rows).tolist() == [[-6, 12, -1, 7]]


def test_a_guard_of_too_many_valuations_is_split_into_conjuncts() -> None:
    flat = _flat("dtmc\nmodule m\n x : [0..1000] init 0;\n y : [0..1000] init 0;\n"
                 "[] x<1000 & y<=x -> (x'=x+1);\nendmodule\n")
    guard = flat.modules[0].commands[0].guard
    builder = LookupBuilder(("x", "y"), {"x": (0, 1000), "y": (0, 1000)}, np.bool_)
    assert builder.add(guard) is None  # 1001 * 1001 valuations
    assert [builder.add(c) for c in conjuncts(guard)] == [0, None]  # y<=x: as many


@pytest.mark.usefixtures("at_once")
def test_a_model_without_variables_has_one_state() -> None:
    """No variable to assign or look up: one state, its self-loop (PRISM's too)."""
    dtmc = build_dtmc(_flat("dtmc\nmodule m\n [] true -> true;\nendmodule\n"))
    assert (dtmc.num_states, dtmc.num_transitions, dtmc.deadlocks) == (1, 1, 0)
