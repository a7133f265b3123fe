"""The builder's memory: frontier chunks sized by their branches, same DTMC either way.

Herman's self-stabilising ring (every process moves on one synchronised action,
each state has up to 2^N successors) is the model where one chunk of states
expands into millions of successor rows; the builder sizes its chunks from the
branching of the chunk before. Peak memory is measured with tracemalloc (numpy
reports its buffers to it); no timing is asserted.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from veribattery.explore.build import builder
from veribattery.explore.build.builder import build_dtmc
from veribattery.explore.dtmc import DTMC
from veribattery.lang import flatten_model, parse_model
from veribattery.lang.nodes import FlatModel


def herman(n: int) -> FlatModel:
    """Herman's ring of *n* processes (as in QVBench), every configuration initial."""
    last = f"x{n}"
    lines = ["dtmc", "const double p = 0.5;", "module process1", "  x1 : [0..1];",
             f"  [step]  (x1={last}) -> p : (x1'=0) + 1-p : (x1'=1);",
             f"  [step] !(x1={last}) -> (x1'={last});", "endmodule"]
    for i in range(2, n + 1):
        lines.append(f"module process{i} = process1 [ x1=x{i}, {last}=x{i - 1} ] endmodule")
    tokens = "+".join(f"(x{i}=x{i % n + 1}?1:0)" for i in range(1, n + 1))
    lines += ['rewards "steps" true : 1; endrewards', "init true endinit",
              f'label "stable" = {tokens}=1;']
    return flatten_model(parse_model("\n".join(lines)))


def _same(a: DTMC, b: DTMC) -> bool:
    P, Q = a.transitions, b.transitions
    return (np.array_equal(a.states, b.states) and np.array_equal(P.indptr, Q.indptr)
            and np.array_equal(P.indices, Q.indices) and np.array_equal(P.data, Q.data)
            and all(np.array_equal(a.labels[k], b.labels[k]) for k in a.labels)
            and np.array_equal(a.rewards[0].state, b.rewards[0].state))


def _unbounded(monkeypatch: pytest.MonkeyPatch) -> None:
    """Chunks of ``_CHUNK`` states whatever their branching (the builder before)."""
    monkeypatch.setattr(builder, "_FIRST_CHUNK", builder._CHUNK)
    monkeypatch.setattr(builder, "_BRANCH_WORDS", 1 << 60)


def test_branch_sized_chunks_give_the_same_dtmc(monkeypatch: pytest.MonkeyPatch) -> None:
    model = herman(9)
    chunked = build_dtmc(model)
    monkeypatch.setattr(builder, "_BRANCH_WORDS", 1 << 10)  # a handful of states per chunk
    tiny = build_dtmc(model)
    _unbounded(monkeypatch)
    whole = build_dtmc(model)
    assert chunked.num_states == 512
    # 2^k successors for k tokens, summed over the configurations (odd n: >= 1 token).
    assert _same(chunked, whole) and _same(tiny, whole)


def test_chunks_adapt_to_the_branching() -> None:
    # 1 branch of 6 variables per state: the largest chunk; 440 branches: about 1,100.
    assert builder._next_chunk(builder._CHUNK, 100, 100, 6) == builder._CHUNK
    assert builder._next_chunk(256, 256, 256, 6) == 1024  # grows at most fourfold
    heavy = builder._next_chunk(builder._CHUNK, 440 * 1000, 1000, 15)
    assert heavy == int(builder._BRANCH_WORDS / (440 * 17))
    assert builder._next_chunk(4, 10**9, 1, 15) == 1


def _explore_peak(model: FlatModel) -> int:
    program = builder.compile_program(model)
    tracemalloc.start()
    try:
        builder.explore(model, program)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_successor_rows_of_a_synchronised_ring_stay_bounded(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    model = herman(11)  # 2,048 states, 177,148 transitions
    monkeypatch.setattr(builder, "_BRANCH_WORDS", 1 << 16)
    bounded = _explore_peak(model)
    _unbounded(monkeypatch)
    whole = _explore_peak(model)
    # The whole frontier at once holds every successor row (11 int64 columns) and
    # the per-part update indices: several times the layers kept for assembly.
    assert bounded < whole / 3
