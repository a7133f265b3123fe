"""Bench: the Fig. 6 sweep end to end against a serial loop of Storm over the emitted files.

    python bench/bench_sweep.py [-j 2] [--stride K] [--optimal]

Like for like: veribattery runs what ``veribattery reproduce fig6`` runs -- the same
axes and ``--set`` strings (:func:`veribattery.analyses.figures.capacity_sets`: the
paper's setting, P(success) as the only property) -- as one whole ``veribattery
sweep`` process (start-up, every point, durable results, the recharge-cap probability
it always reports); Storm (stormpy) runs a serial loop in this process over the files
``veribattery emit`` writes for the same points (parse, build, check P(success);
emitting is not timed). ``--stride K`` keeps every K-th capacity of 5.0-20.0 Ah (all
four models) when the machine is too busy for the whole grid, and the output says so.
Wall and CPU seconds are reported for both sides. Values are compared (1e-6 relative:
Storm's default solver precision). The run's row replaces the previous run's with the
same points (the whole grid, or one subset) in ``docs/_bench/bench_sweep.md``, which
the documentation's performance page includes.

``--optimal`` measures ``reproduce fig6 --optimal``: each point is also swept in
synthesis mode (``--vary strategy.mode=bs1,synthesize``: BS1's P(success) and the
mission MDP's certified ``Pmax``), and Storm's loop also parses, builds and checks
``Pmax=? [ F "success" ]`` on each emitted MDP (its row is marked "+ Pmax").
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
#: The table the performance page (docs/performance.md) includes: the latest run per grid.
TABLE = HERE.parent / "docs" / "_bench" / "bench_sweep.md"
TABLE_HEAD = (
    "Written by `python bench/bench_sweep.py`: the latest run of each grid. veribattery is "
    "the whole `sweep` process, Storm parses, builds and checks each emitted model in one "
    "process; CPU is user + system.\n\n"
    "| when | points | -j | vb wall s | vb CPU s | Storm wall s | Storm CPU s | wall ratio | "
    "vb peak MB | agree | load avg |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|\n"
)
MODELS = ("advanced", "basic_high", "basic_medium", "basic_low")


def capacities(stride: int) -> list[Decimal]:
    """5.0, 5.1, ..., 20.0 Ah, every *stride*-th."""
    return [Decimal(50 + k) / 10 for k in range(0, 151, stride)]


def fig6_sets() -> tuple[str, ...]:
    """The ``--set`` strings ``reproduce fig6`` sweeps with."""
    from veribattery.analyses.figures import capacity_sets

    return capacity_sets(["fig6"])


def run_ours(config: Path, stride: int, jobs: int, results: Path,
             optimal: bool) -> tuple[float, float, float]:
    """Wall seconds, CPU seconds (all processes) and peak RSS (MB, largest process) of
    the whole sweep command."""
    exe = str(Path(sys.executable).parent / "veribattery")
    step = Decimal(stride) / 10
    sets = [arg for item in fig6_sets() for arg in ("--set", item)]
    modes = ["--vary", "strategy.mode=bs1,synthesize"] if optimal else []
    argv = [exe, "sweep", str(config), "--vary", f"battery.model={','.join(MODELS)}",
            "--vary", f"battery.capacity_ah=5:20:{step}", *modes, *sets, "-j", str(jobs),
            "-o", str(results), "--format", "csv"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    subprocess.run(argv, check=True, capture_output=True)
    seconds = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return seconds, cpu, after.ru_maxrss / 1024


#: The emitted files of one point: (model, capacity, property name, folder, formula).
Emitted = tuple[str, Decimal, str, Path, str]


def emit_all(config: Path, caps: list[Decimal], folder: Path,
             optimal: bool) -> list[Emitted]:
    """Emit every point's files (not timed): BS1's DTMC, and with *optimal* the MDP."""
    from veribattery.config import load_config
    from veribattery.config.schema import PAPER_PROPERTIES
    from veribattery.mission import mission_files, write_files
    from veribattery.synthesis import synthesis_files

    points = []
    for model in MODELS:
        for cap in caps:
            cfg = load_config(config, [*fig6_sets(), f"battery.model={model}",
                                       f"battery.capacity_ah={cap}"])
            where = folder / f"{model}-{cap}"
            write_files(mission_files(cfg), where)
            points.append((model, cap, "p_success", where, PAPER_PROPERTIES["p_success"]))
            if optimal:
                write_files(synthesis_files(cfg), where / "mdp")
                points.append((model, cap, "p_success_max", where / "mdp",
                               'Pmax=? [ F "success" ]'))
    return points


Values = dict[tuple[str, str, str], float]


def run_storm(points: list[Emitted]) -> tuple[float, float, Values]:
    """Wall and CPU seconds of Storm's serial loop (parse, build, check) and its value
    per point and property."""
    import stormpy

    values: Values = {}
    started, cpu = time.perf_counter(), time.process_time()
    for model, cap, name, folder, text in points:
        program = stormpy.parse_prism_program(str(folder / "model.prism"))
        props = stormpy.parse_properties(text, program)
        built = stormpy.build_model(program, props)
        init = built.initial_states[0]
        values[(model, _capacity(cap), name)] = float(
            stormpy.model_checking(built, props[0]).get_value(init))
    return time.perf_counter() - started, time.process_time() - cpu, values


def _capacity(text: object) -> str:
    return str(Decimal(str(text)).normalize())


def agree(results: Path, storm: Values) -> bool:
    """Every value within 1e-6 relative of Storm's."""
    ours: dict[tuple[str, str, str], float] = {}
    with results.open() as stream:
        for row in csv.DictReader(stream):
            key = (row["battery.model"], _capacity(row["battery.capacity_ah"]), row["property"])
            ours[key] = float(row["value"])
    for key, theirs in storm.items():
        mine = ours[key]
        if abs(mine - theirs) > 1e-6 * max(abs(mine), abs(theirs), 1e-300):
            print(f"disagree at {key}: ours {mine!r}, Storm {theirs!r}", file=sys.stderr)
            return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("--stride", type=int, default=1,
                        help="keep every K-th capacity (a subset when the machine is busy)")
    parser.add_argument("--optimal", action="store_true",
                        help="also Pmax of the mission MDP at each point (fig6 --optimal)")
    args = parser.parse_args()
    caps = capacities(args.stride)
    subset = "" if args.stride == 1 else f" (SUBSET: every {args.stride}th capacity)"
    subset += " + Pmax" if args.optimal else ""
    print(f"{len(caps) * 4} points{subset}; load average {os.getloadavg()[0]:.1f}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp) / "fig6.yaml"
        config.write_text("{}\n")  # reproduce fig6 sweeps the baseline with --set strings
        ours_s, ours_cpu, peak = run_ours(config, args.stride, args.jobs,
                                          Path(tmp) / "results.csv", args.optimal)
        print(f"veribattery sweep -j {args.jobs}: {ours_s:.1f} s wall, {ours_cpu:.1f} s CPU "
              f"(peak RSS {peak:.0f} MB)", flush=True)
        emitted = emit_all(config, caps, Path(tmp) / "emitted", args.optimal)
        storm_s, storm_cpu, values = run_storm(emitted)
        same = agree(Path(tmp) / "results.csv", values)
    ratio = ours_s / storm_s
    print(f"Storm serial loop: {storm_s:.1f} s wall, {storm_cpu:.1f} s CPU; wall ratio "
          f"{ratio:.2f}, CPU ratio {ours_cpu / storm_cpu:.2f}; values agree: {same}")
    record(len(caps) * 4, subset, args.jobs, (ours_s, ours_cpu), (storm_s, storm_cpu), peak,
           same)


def record(points: int, subset: str, jobs: int, ours: tuple[float, float],
           storm: tuple[float, float], peak: float, same: bool) -> None:
    """Write the run into TABLE, in place of the last run over the same points."""
    day = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    grid = f"{points}{subset}"
    line = (f"| {day} | {grid} | {jobs} | {ours[0]:.1f} | {ours[1]:.1f} | "
            f"{storm[0]:.1f} | {storm[1]:.1f} | {ours[0] / storm[0]:.2f} | {peak:.0f} | "
            f"{'yes' if same else 'NO'} | {os.getloadavg()[0]:.1f} |")
    rows = [r for r in _rows() if r.split("|")[2].strip() != grid]
    TABLE.parent.mkdir(parents=True, exist_ok=True)
    TABLE.write_text(TABLE_HEAD + "\n".join([*rows, line]) + "\n", encoding="utf-8")
    print(f"wrote {TABLE}", file=sys.stderr)


def _rows() -> list[str]:
    """The table rows of the runs recorded so far."""
    if not TABLE.exists():
        return []
    table = [ln for ln in TABLE.read_text(encoding="utf-8").splitlines() if ln.startswith("|")]
    return table[2:]  # below the header and its rule

if __name__ == "__main__":
    main()
