"""``build_compact_dtmc``: the DTMC of ``build_dtmc(...).compact()``, to the last bit,
without the int64 state table (the peak of a build with many variables)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from veribattery.explore import DTMC, build_compact_dtmc, build_dtmc
from veribattery.explore.build.store import StateStore, narrowest_type
from veribattery.lang import flatten_model, parse_model

QCOMP = Path(__file__).resolve().parents[2] / "bench" / "qcomp"

#: A wide range, a negative one and rewards and labels over them (int16 table).
WIDE = """dtmc
module m
  x : [-5..300] init -5;
  b : bool init false;
  [a] x < 300 -> 0.5 : (x'=min(300, x+7)) + 0.5 : (x'=max(-5, min(300, x*2+1))) & (b'=!b);
  [] x = 300 -> true;
endmodule
label "high" = x*x > 40000;
rewards "r"
  x > 0 : x*1000;
  [a] b : x/7;
endrewards
"""

CASES = {
    "crowds": ((QCOMP / "crowds" / "crowds.prism").read_text(),
               {"TotalRuns": 3, "CrowdSize": 5}),
    "nand": ((QCOMP / "nand" / "nand.prism").read_text(), {"N": 5, "K": 1}),
    "brp": ((QCOMP / "brp" / "brp.prism").read_text(), {"N": 16, "MAX": 2}),
    "wide": (WIDE, {}),
}


def _assert_same(a: DTMC, b: DTMC) -> None:
    assert a.states.dtype == b.states.dtype and np.array_equal(a.states, b.states)
    assert (a.transitions != b.transitions).nnz == 0
    assert np.array_equal(a.transitions.data, b.transitions.data)
    assert np.array_equal(a.initial, b.initial)
    assert a.labels.keys() == b.labels.keys()
    assert all(np.array_equal(a.labels[k], b.labels[k]) for k in a.labels)
    assert len(a.rewards) == len(b.rewards)
    for x, y in zip(a.rewards, b.rewards, strict=True):
        assert np.array_equal(x.state, y.state) and np.array_equal(x.transition, y.transition)
    assert (a.deadlocks, a.warnings) == (b.deadlocks, b.warnings)


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_compact_build_is_the_compacted_dtmc(name: str) -> None:
    text, constants = CASES[name]
    flat = flatten_model(parse_model(text), constants)
    full = build_dtmc(flat)
    compact = build_compact_dtmc(flat)
    assert full.states.dtype == np.int64
    _assert_same(full.compact(), compact)
    assert np.array_equal(full.states, compact.states)  # the same values, only narrower


def test_the_wide_model_needs_int16_and_its_rewards_are_not_wrapped() -> None:
    flat = flatten_model(parse_model(WIDE), {})
    dtmc = build_compact_dtmc(flat)
    assert dtmc.states.dtype == np.int16
    x = dtmc.column("x").astype(np.int64)
    assert x.max() == 300
    # x*1000 and x*x overflow int16: the rewards and labels are still those over int64.
    assert np.array_equal(dtmc.reward("r").state, np.where(x > 0, x * 1000.0, 0.0))
    assert np.array_equal(dtmc.labels["high"], x * x > 40000)


@pytest.mark.parametrize(("low", "high", "kind"), [
    (0, 1, np.int8), (-128, 127, np.int8), (-129, 0, np.int16), (0, 40_000, np.int32),
    (0, 1 << 40, np.int64)])
def test_narrowest_type(low: int, high: int, kind: type) -> None:
    assert narrowest_type(low, high) is kind


def test_compact_states_decode_in_blocks_to_the_declared_ranges_type() -> None:
    store = StateStore([-3, 0], [3, 1000])
    rows = np.array([[x % 7 - 3, (37 * x) % 1001] for x in range(200_000)], dtype=np.int64)
    store.add(rows)
    compact = store.compact_states
    assert compact.dtype == np.int16
    assert np.array_equal(compact, store.states)
