"""A BFS layer wider than one chunk (a model whose ``init`` block holds every state, as
herman's) reports progress and is watched for memory chunk by chunk, not only at its
end: herman 19's first layer of 524,288 states took minutes with nothing printed. A
wide first layer is first judged from a uniform sample of its states: herman 21's first
chunk alone held 15 GB of successors before it could be refused. The MDP builder is
watched chunk by chunk too."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.patched_cli import last_error_line, run_patched
from veribattery.errors import ModelError, ModelTooLarge
from veribattery.explore.build import guard, sample
from veribattery.explore.build.builder import (
    build_dtmc,
    expand_frontier,
    explore,
    initial_states,
    memory_footprint,
)
from veribattery.explore.build.mdp import build_mdp
from veribattery.explore.build.store import StateStore
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


# 20,000 initial states (wider than a chunk): x < 100 has eight branches per state (a
# heavy front, as herman's states of many tokens), the rest two: 40,600 transitions.
HEAVY_FRONT = """dtmc
const int N = 20000;
module m
  x : [0..N-1];
  [] x<100 -> 0.125:(x'=mod(x+1, N)) + 0.125:(x'=mod(x+2, N)) + 0.125:(x'=mod(x+3, N))
      + 0.125:(x'=mod(x+4, N)) + 0.125:(x'=mod(x+5, N)) + 0.125:(x'=mod(x+6, N))
      + 0.125:(x'=mod(x+7, N)) + 0.125:(x'=mod(x+8, N));
  [] x>=100 -> 0.5:(x'=mod(x+1, N)) + 0.5:(x'=mod(x+N-1, N));
endmodule
init true endinit
"""


def _sample_of(text: str) -> sample.BranchSample:
    flat = flatten_model(parse_model(text))
    program = compile_program(flat)
    store = StateStore(program.lows, program.highs)
    store.add(initial_states(flat))

    def branches_of(rows: np.ndarray) -> np.ndarray:
        found = expand_frontier(program, rows, set())
        return np.bincount(found.source, minlength=rows.shape[0])

    found = sample.sampled_branches(store.rows_at, branches_of, 0, store.count)
    assert found is not None
    return found


def test_a_uniform_sample_estimates_a_layer_whose_front_is_heavy() -> None:
    found = _sample_of(HEAVY_FRONT)
    assert found.size == 2048
    # The true mean is 40,600 / 20,000 = 2.03; the first chunk's (x < 256) would say 4.3.
    assert abs(found.mean - 2.03) < 4 * found.error + 1e-12
    assert found.at_least(20_000, 4.0) <= 40_600 <= found.mean * 20_000 + 4 * found.error * 20_000


def test_sample_statistics_are_the_sample_mean_and_its_standard_error() -> None:
    counts = np.arange(10_000) % 7  # branches of state i: i mod 7
    found = sample.sampled_branches(lambda index: index[:, None], lambda rows: counts[rows[:, 0]],
                                    0, counts.size, size=1000)
    assert found is not None
    picked = np.sort(np.random.default_rng(0).choice(10_000, size=1000, replace=False))
    assert found.mean == pytest.approx(counts[picked].mean(), rel=1e-15)
    expected = counts[picked].std(ddof=1) / np.sqrt(1000) * np.sqrt(1 - 1000 / 10_000)
    assert found.error == pytest.approx(expected, rel=1e-12)
    # A layer no larger than the sample is expanded whole: its mean exactly, no error.
    whole = sample.sampled_branches(lambda index: index[:, None], lambda rows: counts[rows[:, 0]],
                                    0, 500, size=1000)
    assert whole is not None and whole.size == 500 and whole.error == 0.0
    assert whole.mean == pytest.approx(counts[:500].mean(), rel=1e-15)


def test_a_model_error_in_the_sample_is_left_to_the_search() -> None:
    def failing(rows: np.ndarray) -> np.ndarray:
        raise ModelError("x out of range")

    assert sample.sampled_branches(lambda index: index[:, None], failing, 0, 100) is None


def test_a_wide_first_layer_is_refused_from_its_sample_before_any_chunk(
        monkeypatch: pytest.MonkeyPatch) -> None:
    flat = flatten_model(parse_model(HEAVY_FRONT))
    program = compile_program(flat)
    footprint = memory_footprint(program)
    monkeypatch.setattr(guard, "_NEGLIGIBLE", 0)
    monkeypatch.setattr(guard, "_USABLE", 1.0)
    # Room for about 30,000 transitions: the layer's 40,600 do not fit.
    room = footprint.assembled(20_000, 30_000) - footprint.searching(20_000, 0)
    seen: list[tuple[int, int]] = []
    with pytest.raises(ModelTooLarge, match=r"the 20,000 states of the first layer have "
                                            r"about 4\d,\d{3} transitions \(at least 3\d,\d{3}, "
                                            r"from a uniform sample of 2,048 of them\)"):
        explore(flat, program, lambda s, f: seen.append((s, f)),
                guard.MemoryGuard(footprint, lambda: room))
    assert seen == []  # refused before the first chunk was expanded
    # With room for 50,000 the sample lets it through; the whole layer is built.
    room = footprint.assembled(20_000, 50_000) - footprint.searching(20_000, 0)
    states, _, _ = explore(flat, program, guard=guard.MemoryGuard(footprint, lambda: room))
    assert states.shape[0] == 20_000


# An MDP of 20,000 states in a ring, two choices each (one step either way, or stay).
MDP_RING = """mdp
const int N = 20000;
module m
  x : [0..N-1] init 0;
  [go] true -> 0.5:(x'=mod(x+1, N)) + 0.5:(x'=mod(x+2, N));
  [stay] true -> (x'=x);
endmodule
"""


def test_an_mdp_build_is_refused_once_what_it_found_would_not_fit(
        monkeypatch: pytest.MonkeyPatch) -> None:
    flat = flatten_model(parse_model(MDP_RING))
    footprint = memory_footprint(compile_program(flat))
    monkeypatch.setattr(guard, "_NEGLIGIBLE", 0)
    monkeypatch.setattr(guard, "_USABLE", 1.0)
    # Room for the first chunks' transitions, not for all 60,000.
    room = footprint.assembled(20_000, 20_000) - footprint.searching(20_000, 20_000)
    with pytest.raises(ModelTooLarge, match=r"transitions found so far, [\d,]+ states "
                                            r"expanded; going on needs about"):
        build_mdp(flat, guard=guard.MemoryGuard(footprint, lambda: room))
    roomy = footprint.assembled(20_000, 60_000)
    built = build_mdp(flat, guard=guard.MemoryGuard(footprint, lambda: roomy))
    assert built.transitions.shape == (40_000, 20_000) and built.transitions.nnz == 60_000


def test_an_mdp_too_large_for_memory_is_one_line_and_status_2(tmp_path: Path) -> None:
    """As a user meets it: ``veribattery prism`` on the MDP, with the memory the
    system reports made small (the guard reads MemAvailable)."""
    (tmp_path / "ring.nm").write_text(MDP_RING)
    starve = ("from veribattery.explore.build import guard\n"
              "guard._NEGLIGIBLE = 0\n"
              "guard.available_memory = lambda: 1 << 20")
    last = last_error_line(run_patched(starve, ["prism", "ring.nm", "--property",
                                                "Pmax=? [ F x=N-1 ]"], tmp_path))
    assert last.startswith("error: model too large for the memory available: ") and (
        "states expanded; going on needs about" in last and "0.0 GB available" in last), last
