"""A BFS layer wider than one chunk (a model whose ``init`` block holds every state, as
herman's) reports progress and is watched for memory chunk by chunk, not only at its
end: herman 19's first layer of 524,288 states took minutes with nothing printed."""

from __future__ import annotations

import pytest

from veribattery.errors import ModelTooLarge
from veribattery.explore.build import guard
from veribattery.explore.build.builder import build_dtmc, explore, memory_footprint
from veribattery.explore.compile.program import compile_program
from veribattery.lang import flatten_model, parse_model

# 4,096 initial states (all of them), each moving one step left or right: one layer.
RING = """dtmc
module m
  x : [0..4095];
  [] true -> 0.5:(x'=mod(x+1, 4096)) + 0.5:(x'=mod(x+4095, 4096));
endmodule
init true endinit
"""


def test_a_wide_layer_reports_progress_chunk_by_chunk() -> None:
    seen: list[tuple[int, int]] = []
    dtmc = build_dtmc(flatten_model(parse_model(RING)),
                      progress=lambda states, frontier: seen.append((states, frontier)))
    assert dtmc.num_states == 4096 and dtmc.num_transitions == 8192
    # Chunks of 256, 1024 and 2048 states (each at most four times the one before)
    # leave 3,840, 2,816 and then nothing of the layer; the layer's own report ends it.
    assert seen == [(4096, 3840), (4096, 2816), (4096, 4096)]


def test_a_wide_layer_is_refused_inside_once_what_it_found_would_not_fit(
        monkeypatch: pytest.MonkeyPatch) -> None:
    flat = flatten_model(parse_model(RING))
    program = compile_program(flat)
    footprint = memory_footprint(program)
    # Enough to search the first chunk's 512 transitions, not to assemble them as well.
    room = int(footprint.assembled(4096, 512) - footprint.searching(4096, 512)) - 1
    monkeypatch.setattr(guard, "_NEGLIGIBLE", 0)
    monkeypatch.setattr(guard, "_USABLE", 1.0)
    watcher = guard.MemoryGuard(footprint, lambda: room)
    with pytest.raises(ModelTooLarge, match="256 of a layer of 4,096 states expanded"):
        explore(flat, program, guard=watcher)
