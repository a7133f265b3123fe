"""The fused layer expansion equals the group-by-group one, bit for bit, layer by layer."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import PEER_TESTS
from tests.peer_manifests import assert_enough, fail_missing, manifest, missing
from veribattery.errors import ModelError
from veribattery.explore import build_dtmc
from veribattery.explore.build import builder as builder_module
from veribattery.explore.build.builder import Layer, explore
from veribattery.explore.build.plan import plan_layers
from veribattery.explore.compile.program import compile_program
from veribattery.lang.nodes import FlatModel
from veribattery.lang.parser import parse_model
from veribattery.lang.semantics import flatten_model

MODELS = {
    # several commands in one module, some overlapping (1/n weighting), a deadlock
    "nondeterministic": """dtmc
module m
  x : [0..5] init 0;
  [] x<3 -> 0.5:(x'=x+1) + 0.5:(x'=0);
  [] x=1 -> (x'=4);
  [] x=2 -> 0.25:(x'=5) + 0.75:true;
endmodule
""",
    # synchronisation with several commands per part: a product of choices
    "product": """dtmc
module a
  x : [0..3] init 0;
  [s] x<3 -> 0.3:(x'=x+1) + 0.7:true;
  [s] x>0 -> (x'=x-1);
  [] x=3 -> (x'=0);
endmodule
module b
  y : [0..2] init 0;
  [s] y<2 -> 0.6:(y'=y+1) + 0.4:(y'=0);
  [s] y=2 -> (y'=0);
  [s] y>=1 -> 1/(y+1):(y'=y-1) + 1-1/(y+1):true;
endmodule
rewards "r"
  [s] true : 1;
  [] x=3 : 2;
endrewards
""",
    # state-dependent probabilities, a division guarded by its command, booleans,
    # a zero-probability branch (dropped) and an assignment from another module's variable
    "expressions": """dtmc
const int N = 6;
module c
  n : [0..N] init 0;
  f : bool init false;
  [go] n<N -> n/N:(n'=n+1) + 1-n/N:(n'=n+1)&(f'=!f) + 0:(n'=0);
  [go] n=N -> (n'=floor(N/(n-N+1)) - N);
  [] f & n=N -> (f'=false);
endmodule
module d
  m : [0..N] init 1;
  [go] m>0 -> (m'=min(N, floor(12/m)));
  [go] m=0 -> (m'=n);
endmodule
""",
}


def _layers(model: FlatModel, fused: bool) -> tuple[np.ndarray, np.ndarray, list[Layer]]:
    saved = builder_module.layer_plan
    if not fused:
        builder_module.layer_plan = lambda program: None  # type: ignore[assignment]
    try:
        return explore(model, compile_program(model))
    finally:
        builder_module.layer_plan = saved


def _assert_same_exploration(model: FlatModel) -> None:
    states, initial, layers = _layers(model, fused=True)
    expected_states, expected_initial, expected = _layers(model, fused=False)
    np.testing.assert_array_equal(states, expected_states)
    np.testing.assert_array_equal(initial, expected_initial)
    assert len(layers) == len(expected)
    for got, want in zip(layers, expected, strict=True):
        for name in ("rows", "columns", "probabilities", "choices", "dropped"):
            np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
        assert got.probabilities.tobytes() == want.probabilities.tobytes()  # bit for bit
        assert got.branches == want.branches
        assert got.action_choices.keys() == want.action_choices.keys()
        for action, counts in want.action_choices.items():
            np.testing.assert_array_equal(got.action_choices[action], counts)


@pytest.mark.parametrize("name", MODELS)
def test_fused_equals_group_by_group(name: str) -> None:
    model = flatten_model(parse_model(MODELS[name]), {})
    assert plan_layers(compile_program(model)) is not None  # the fused path is exercised
    _assert_same_exploration(model)


def test_hand_solved_product_chain() -> None:
    """Counts and probabilities of the product model, worked out by hand from the start."""
    dtmc = build_dtmc(flatten_model(parse_model(MODELS["product"]), {}))
    matrix = dtmc.transitions.toarray()
    start = int(dtmc.initial[0])
    row = {tuple(int(v) for v in dtmc.states[j]): matrix[start, j] for j in range(dtmc.num_states)
           if matrix[start, j]}
    # From (0,0): a's first [s] (x<3) with b's first [s] (y<2); one choice.
    assert row == pytest.approx({(1, 1): 0.18, (1, 0): 0.12, (0, 1): 0.42, (0, 0): 0.28})
    np.testing.assert_allclose(matrix.sum(axis=1), 1.0)


def test_layer_with_an_error_is_located_by_the_slow_path() -> None:
    text = """dtmc
module m
  x : [0..3] init 0;
  [] x<3 -> (x'=x+2);
  [] x=3 -> true;
endmodule
"""
    with pytest.raises(ModelError, match=r"update sets x to 4, outside its range 0\.\.3"):
        build_dtmc(flatten_model(parse_model(text), {}))


_LATER_PART_DIVIDES = """dtmc
module a
  x : [0..3] init 0;
  [s] x<GUARD -> (x'=min(3, x+1));
  [t] x=3 -> (x'=0);
endmodule
module b
  y : [0..1] init 0;
  [s] floor(6/(3-x)) >= 2 -> (y'=1-y);
  [s] floor(6/(3-x)) < 2 -> true;
endmodule
"""


def test_later_part_guard_is_not_evaluated_where_the_first_part_disables_it() -> None:
    """At x=3 module a disables [s], so b's guards (floor(6/0): no int there) are not
    evaluated: by either path, as PRISM's semantics of the synchronised command."""
    model = flatten_model(parse_model(_LATER_PART_DIVIDES.replace("GUARD", "3")), {})
    _assert_same_exploration(model)
    dtmc = build_dtmc(model)
    # (0,0) -> (1,1) -> (2,0) -> (3,1) -> (0,1) -> (1,0) -> (2,1) -> (3,0) -> (0,0)
    assert dtmc.num_states == 8
    assert dtmc.transitions.nnz == 8
    np.testing.assert_array_equal(dtmc.transitions.data, np.ones(8))


def test_later_part_guard_error_is_reported_where_the_first_part_enables_it() -> None:
    model = flatten_model(parse_model(_LATER_PART_DIVIDES.replace("GUARD", "=3")), {})
    with pytest.raises(ModelError, match="cannot take floor of inf"):
        build_dtmc(model)


def test_bad_probability_sum_is_reported() -> None:
    text = """dtmc
module m
  x : [0..3] init 0;
  [] x<3 -> x/10:(x'=x+1) + 0.5:true;
  [] x=3 -> true;
endmodule
"""
    with pytest.raises(ModelError, match=r"probabilities sum to 0\.5, not 1, in state"):
        build_dtmc(flatten_model(parse_model(text), {}))


def _peer_cases(limit: int) -> list[Any]:
    data = manifest("prism-examples")
    if data is None:
        return [missing("prism-examples", None)]
    return [
        pytest.param((m["model"], s["constants"]),
                     id=f"{Path(m['model']).stem}{sorted(s['constants'].items())}")
        for m in data["models"]
        for s in m["settings"]
        if s["states"] <= limit
    ]


PEER = _peer_cases(20_000)


def test_enough_peer_models_are_compared() -> None:
    """All 9 settings of prism-examples were at most 20,000 states when this was written."""
    assert_enough(sum(p.values[0] is not None for p in PEER), 9, "prism-examples settings")


@pytest.mark.parametrize("case", PEER)
def test_fused_equals_group_by_group_on_peer_models(
    case: tuple[str, dict[str, str]] | None,
) -> None:
    if case is None:
        fail_missing("prism-examples")
    path = PEER_TESTS / "prism-examples" / case[0]
    _assert_same_exploration(flatten_model(parse_model(path), case[1]))


@pytest.mark.parametrize(
    ("update", "message"),
    [
        ("x-4", r"update sets x to -3, outside its range -2\.\.3"),  # below a negative low
        ("x+5", r"update sets x to 6, outside its range -2\.\.3"),
        # int64 overflow: wraps to a huge negative value, still out of range
        ("x*4611686018427387904*2", r"outside its range -2\.\.3"),
    ],
)
def test_out_of_range_targets_fall_back_and_are_located(update: str, message: str) -> None:
    text = f"""dtmc
module m
  x : [-2..3] init 0;
  [] x=0 -> (x'=1);
  [] x=1 -> (x'={update});
  [] x!=0 & x!=1 -> true;
endmodule
"""
    model = flatten_model(parse_model(text), {})
    plan = plan_layers(compile_program(model))
    assert plan is not None
    assert plan.expand(np.array([[1]]), set()) is None  # the fused path gives the layer up
    assert plan.expand(np.array([[0]]), set()) is not None
    with pytest.raises(ModelError, match=message):
        build_dtmc(model)


def test_range_check_reads_offsets_unsigned() -> None:
    """``_out_of_range`` flags exactly the targets outside [low, high], int64 extremes too."""
    from veribattery.explore.build.fused import _out_of_range

    model = flatten_model(parse_model("""dtmc
module m
  x : [-5..7] init 0;
  y : [0..3] init 0;
  [] true -> true;
endmodule
"""), {})
    plan = plan_layers(compile_program(model))
    assert plan is not None
    info = np.iinfo(np.int64)
    for x in (-6, 8, info.min, info.max, info.min + 1, -5 - (1 << 62)):
        assert _out_of_range(plan, np.array([[0, 0], [x, 0]], dtype=np.int64)), x
    for x in (-5, 0, 7):
        for y in (0, 3):
            assert not _out_of_range(plan, np.array([[x, y]], dtype=np.int64))
    assert _out_of_range(plan, np.array([[0, -1]], dtype=np.int64))
    assert _out_of_range(plan, np.array([[0, 4]], dtype=np.int64))
