"""The builder's per-layer cost outside the expansion: the state store and the layer loop.

    python bench/bench_layers.py MODEL.prism [--repeat N] [--const NAME=VALUE ...]

In one process: builds *MODEL* ``--repeat`` times after a warm-up and prints the
best CPU times (``time.process_time``) of the build stage (explore + assemble,
compiling excluded), of explore minus the layers' expansion (the store and the
layer loop), per expansion, and of assembling; then replays the store's batches of
that build (every ``StateStore.add`` and ``rows`` call, recorded) on a fresh store
and prints the best time per batch. Run it for two checkouts back to back
(``PYTHONPATH=OTHER/src python bench/bench_layers.py ...``) to compare them:
on a shared machine only such alternating runs are comparable.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from veribattery.explore.build import builder, store
from veribattery.explore.compile.program import compile_program
from veribattery.lang import flatten_model, parse_model


def _constants(pairs: list[str]) -> dict[str, Any]:
    found: dict[str, Any] = {}
    for pair in pairs:
        name, value = pair.split("=", 1)
        found[name] = int(value) if value.lstrip("-").isdigit() else float(value)
    return found


def build_times(model: Any, repeat: int) -> tuple[float, float, float, int]:
    """Best (build stage, explore minus expansion, assemble) CPU seconds, and expansions."""
    expand = builder.expand_frontier
    spent = [0.0, 0]

    def timed(*args: Any) -> Any:
        start = time.process_time()
        found = expand(*args)
        spent[0] += time.process_time() - start
        spent[1] += 1
        return found

    builder.expand_frontier = timed  # type: ignore[assignment]
    runs = []
    try:
        for _ in range(repeat + 1):  # the first is a warm-up
            spent[:] = [0.0, 0]
            program = compile_program(model)
            start = time.process_time()
            states, initial, layers = builder.explore(model, program)
            explored = time.process_time()
            builder.assemble(model, states, initial, layers)
            done = time.process_time()
            runs.append((done - start, explored - start - spent[0], done - explored))
    finally:
        builder.expand_frontier = expand  # type: ignore[assignment]
    best = [min(r[i] for r in runs[1:]) for i in range(3)]
    return best[0], best[1], best[2], int(spent[1])


def record_batches(model: Any) -> list[tuple[Any, ...]]:
    """The store's calls during one build: the constructor's, ``add``'s and ``rows``'."""
    calls: list[tuple[Any, ...]] = []
    cls = store.StateStore
    init, add, rows = cls.__init__, cls.add, cls.rows

    def recorded_init(self: Any, lows: Any, highs: Any) -> None:
        calls.append(("init", list(lows), list(highs)))
        init(self, lows, highs)

    def recorded_add(self: Any, batch: Any) -> Any:
        calls.append(("add", batch.copy()))
        return add(self, batch)

    def recorded_rows(self: Any, low: int, high: int) -> Any:
        calls.append(("rows", low, high))
        return rows(self, low, high)

    cls.__init__, cls.add, cls.rows = recorded_init, recorded_add, recorded_rows  # type: ignore[method-assign]
    try:
        builder.build_dtmc(model)
    finally:
        cls.__init__, cls.add, cls.rows = init, add, rows  # type: ignore[method-assign]
    return calls


def replay(calls: list[tuple[Any, ...]], repeat: int) -> float:
    """Best CPU seconds of replaying *calls* on a fresh store."""
    best = float("inf")
    for _ in range(repeat):
        start = time.process_time()
        fresh: Any = None
        for call in calls:
            if call[0] == "init":
                fresh = store.StateStore(call[1], call[2])
            elif call[0] == "add":
                fresh.add(call[1])
            else:
                fresh.rows(call[1], call[2])
        best = min(best, time.process_time() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("model", type=Path)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--const", action="append", default=[])
    args = parser.parse_args()
    model = flatten_model(parse_model(args.model.read_text()), _constants(args.const))
    build, own, assemble, layers = build_times(model, args.repeat)
    calls = record_batches(model)
    batches = sum(1 for call in calls if call[0] == "add")
    replayed = replay(calls, args.repeat)
    print(f"{args.model} ({store.__file__}):")
    print(f"  build stage {build:.3f} s; explore minus expansion {own * 1e3:.0f} ms "
          f"= {own / layers * 1e6:.0f} us per expansion ({layers}); assemble "
          f"{assemble * 1e3:.0f} ms")
    print(f"  store replayed: {replayed * 1e3:.0f} ms for {batches} batches "
          f"= {replayed / batches * 1e6:.0f} us per batch")


if __name__ == "__main__":
    main()
