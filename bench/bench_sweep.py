"""Bench: the Fig. 6 sweep end to end against a serial loop of Storm over the emitted files.

    python bench/bench_sweep.py [-j 2] [--stride K]

veribattery runs as one whole ``veribattery sweep`` process (start-up, every point,
durable results), Storm (stormpy) as a serial loop in this process over the files
``veribattery emit`` writes for the same points (parse, build, check the three
properties; emitting is not timed). ``--stride K`` keeps every K-th capacity of
5.0-20.0 Ah (all four models) when the machine is too busy for the whole grid, and the
output says so. Values are compared (1e-6 relative: Storm's default solver precision).
A row is appended to ``bench/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import os
import resource
import subprocess
import sys
import tempfile
import time
from decimal import Decimal
from pathlib import Path

HERE = Path(__file__).resolve().parent
MODELS = ("advanced", "basic_high", "basic_medium", "basic_low")


def capacities(stride: int) -> list[Decimal]:
    """5.0, 5.1, ..., 20.0 Ah, every *stride*-th."""
    return [Decimal(50 + k) / 10 for k in range(0, 151, stride)]


def run_ours(config: Path, stride: int, jobs: int, results: Path) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB, largest process) of the whole sweep command."""
    exe = str(Path(sys.executable).parent / "veribattery")
    step = Decimal(stride) / 10
    argv = [exe, "sweep", str(config), "--vary", f"battery.model={','.join(MODELS)}",
            "--vary", f"battery.capacity_ah=5:20:{step}", "-j", str(jobs),
            "-o", str(results), "--format", "csv"]
    started = time.perf_counter()
    subprocess.run(argv, check=True, capture_output=True)
    seconds = time.perf_counter() - started
    return seconds, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024


def emit_all(config: Path, caps: list[Decimal], folder: Path) -> list[tuple[str, Decimal, Path]]:
    """Emit every point's files (not timed)."""
    from veribattery.config import load_config
    from veribattery.mission import mission_files, write_files

    points = []
    for model in MODELS:
        for cap in caps:
            where = folder / f"{model}-{cap}"
            cfg = load_config(config, [f"battery.model={model}", f"battery.capacity_ah={cap}"])
            write_files(mission_files(cfg), where)
            points.append((model, cap, where))
    return points


Values = dict[tuple[str, str], list[float]]


def run_storm(points: list[tuple[str, Decimal, Path]]) -> tuple[float, Values]:
    """Seconds of Storm's serial loop (parse, build, check) and its values per point."""
    import stormpy

    from veribattery.config.schema import PAPER_PROPERTIES

    text = ";".join(PAPER_PROPERTIES.values())
    values: Values = {}
    started = time.perf_counter()
    for model, cap, folder in points:
        program = stormpy.parse_prism_program(str(folder / "model.prism"))
        props = stormpy.parse_properties(text, program)
        built = stormpy.build_model(program, props)
        init = built.initial_states[0]
        values[(model, str(cap))] = [float(stormpy.model_checking(built, p).get_value(init))
                                     for p in props]
    return time.perf_counter() - started, values


def agree(results: Path, storm: Values) -> bool:
    """Every value within 1e-6 relative of Storm's."""
    ours: dict[tuple[str, str], list[float]] = {}
    with results.open() as stream:
        for row in csv.DictReader(stream):
            key = (row["battery.model"], str(Decimal(row["battery.capacity_ah"]).normalize()))
            ours.setdefault(key, []).append(float(row["value"]))
    for (model, cap), theirs in storm.items():
        mine = ours[(model, str(Decimal(cap).normalize()))]
        for a, b in zip(mine, theirs, strict=True):
            if abs(a - b) > 1e-6 * max(abs(a), abs(b), 1e-300):
                return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("--stride", type=int, default=1,
                        help="keep every K-th capacity (a subset when the machine is busy)")
    args = parser.parse_args()
    caps = capacities(args.stride)
    subset = "" if args.stride == 1 else f" (SUBSET: every {args.stride}th capacity)"
    print(f"{len(caps) * 4} points{subset}; load average {os.getloadavg()[0]:.1f}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp) / "fig6.yaml"
        config.write_text("strategy:\n  safe_t: 0.3\nenvironment:\n  p_wsp_c: 0.1\n")
        ours_s, peak = run_ours(config, args.stride, args.jobs, Path(tmp) / "results.csv")
        print(f"veribattery sweep -j {args.jobs}: {ours_s:.1f} s (peak RSS {peak:.0f} MB)",
              flush=True)
        storm_s, values = run_storm(emit_all(config, caps, Path(tmp) / "emitted"))
        same = agree(Path(tmp) / "results.csv", values)
    ratio = ours_s / storm_s
    print(f"Storm serial loop: {storm_s:.1f} s; ratio {ratio:.2f}; values agree: {same}")
    record(len(caps) * 4, subset, args.jobs, ours_s, storm_s, peak, same)


def record(points: int, subset: str, jobs: int, ours: float, storm: float, peak: float,
           same: bool) -> None:
    """Append the run to bench/RESULTS.md."""
    day = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    line = (f"| {day} | {points}{subset} | {jobs} | {ours:.1f} | {storm:.1f} | "
            f"{ours / storm:.2f} | {peak:.0f} | {'yes' if same else 'NO'} | "
            f"{os.getloadavg()[0]:.1f} |\n")
    path = HERE / "RESULTS.md"
    text = path.read_text()
    header = "## Fig. 6 sweep vs a serial Storm loop (`python bench/bench_sweep.py`)"
    if header not in text:
        text += (f"\n{header}\n\nWall-clock seconds; veribattery is the whole `sweep` process, "
                 "Storm parses, builds and checks each emitted model in one process.\n\n"
                 "| when | points | -j | veribattery s | Storm s | ratio | vb peak MB | agree "
                 "| load avg |\n|---|---|---|---|---|---|---|---|---|\n")
    path.write_text(text + line)


if __name__ == "__main__":
    main()
