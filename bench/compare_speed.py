"""Speed and memory of a base revision against the working tree, side by side in one run.

    python bench/compare_speed.py BASE [-n 2] [--quick] [--only case1,mission,...]
    make compare-speed BASE=8887d91

BASE is checked out with ``git worktree add`` into a temporary folder (or given with
``--base-dir``); both trees run under this interpreter with ``PYTHONPATH=<tree>/src``,
byte-compiled first. Each measurement is a fresh process (``os.wait4``: wall clock,
CPU = user + system of the process and the children it waited for, peak RSS of the
largest); every benchmark runs ``-n`` times per tree, base and work alternating (the
order flips every round), and the tables give the minimum wall and CPU seconds, the
largest peak RSS, and the ratios work/base. The benchmarks:

- ``case1``: ``veribattery check configs/paper/case1.yaml --format json``; Storm (stormpy
  in one process: parse, build, check) on the emitted files, all five properties.
- ``mission``: the same check on the 11x11 farm based at [5, 5] with 20 Ah (1.4 million
  states; Storm takes about 5 minutes on it, so it is not run).
- ``models``: ``make bench``'s models (``bench/models.py``: grid walks and synchronised
  counters, the sizes of ``bench_models.py``), ``veribattery prism --json`` each; Storm
  through ``bench/run_one.py``; the ratio to Storm is bench_models's, engine seconds
  (parse + build + check, from the JSON's ``timings_s``) over Storm's.
- ``hm``: ``make bench``'s Haddad-Monmege chain (N = 20, 100, 300), ``prism --json``.
- ``reuse``: each tree's own ``bench/bench_reuse.py --points P`` (its two in-process
  totals are shown too).
- ``sweep``: the Fig. 6 sweep of ``bench/bench_sweep.py`` (``veribattery sweep -j 2``
  over the four battery models and every K-th capacity), against the same serial Storm
  loop over the emitted points (ratio of wall seconds, as bench_sweep.py computes it).

Storm runs once per benchmark, between the first base and work runs. Nothing is
written into the repository. ``--quick``: one round, the small models, 5 reuse points,
a 12-point sweep. Cost: about 1 CPU-minute quick, 5 by default (2026-11-26, on the
2-core machine at load 13: 3.6 and 20 minutes of wall time); on a shared machine
compare the CPU columns, and run more rounds (-n) before trusting a 5 % difference.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path
from typing import Any

from models import BenchModel, counters, grid_walk
from trees import REPO, Tree, base_tree, working_tree

HERE = Path(__file__).resolve().parent
CASE1 = REPO / "configs" / "paper" / "case1.yaml"
#: The 11x11 / 20 Ah mission of docs/performance.md and bench_build.py --big.
MISSION_11X11 = ("--set", "farm.cols=11", "--set", "farm.rows=11", "--set", "farm.base=[5,5]",
                 "--set", "battery.capacity_ah=20")
FULL_MODELS = (grid_walk(100), grid_walk(316), grid_walk(448), grid_walk(1000),
               counters(3, 58), counters(4, 31))  # bench_models.FULL
QUICK_MODELS = (grid_walk(100), counters(3, 20))  # bench_models.QUICK
HM_SIZES = (20, 100, 300)
SWEEP_MODELS = ("advanced", "basic_high", "basic_medium", "basic_low")
BENCHES = ("case1", "mission", "models", "hm", "reuse", "sweep")

STORM_CHECK = """
import json, sys, time, stormpy
start = time.perf_counter()
prog = stormpy.parse_prism_program(sys.argv[1])
props = stormpy.parse_properties("\\n".join(open(f).read() for f in sys.argv[2:]), prog)
model = stormpy.build_model(prog, props)
init = model.initial_states[0]
values = [str(stormpy.model_checking(model, p).get_value(init)) for p in props]
print(json.dumps({"total_s": time.perf_counter() - start, "values": values}))
"""
STORM_SWEEP = """
import json, sys, time, stormpy
start = time.perf_counter()
for folder in sys.argv[1:]:
    prog = stormpy.parse_prism_program(folder + "/model.prism")
    lines = open(folder + "/properties.props").read().splitlines()
    text = next(line for line in lines if line.startswith('"p_success"'))
    props = stormpy.parse_properties(text, prog)
    model = stormpy.build_model(prog, props)
    stormpy.model_checking(model, props[0]).get_value(model.initial_states[0])
print(json.dumps({"total_s": time.perf_counter() - start}))
"""


@dataclass(frozen=True)
class Sample:
    """One process: wall and CPU seconds, peak RSS (MB), and what it printed."""

    wall: float
    cpu: float
    peak_mb: float
    stdout: str


@dataclass
class Row:
    """One benchmark's figures, per tree."""

    name: str
    samples: dict[str, list[Sample]] = field(default_factory=lambda: {"base": [], "work": []})
    #: Extra per-tree figures (seconds) parsed from the output, by name: min over rounds.
    parts: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    storm_s: float | None = None
    storm_what: str = ""
    #: The seconds compared with Storm's, from a sample (None: the whole wall time).
    engine: Callable[[Sample], float] | None = None


class Runner:
    """Runs processes with a memory cap and a time limit."""

    def __init__(self, memory_gb: float, timeout: float) -> None:
        self.memory = int(memory_gb * 2**30) if memory_gb > 0 else None
        self.timeout = timeout

    def run(self, argv: Sequence[str], env: dict[str, str] | None = None,
            cwd: Path | None = None) -> Sample:
        """One process, measured; stops the comparison if it fails."""
        with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
            start = time.perf_counter()
            proc = subprocess.Popen(argv, stdout=out, stderr=err, env=env, cwd=cwd,
                                    preexec_fn=self._limit, start_new_session=True)
            status, usage = self._wait(proc)
            wall = time.perf_counter() - start
            out.seek(0)
            err.seek(0)
            stdout = out.read().decode(errors="replace")
            stderr = err.read().decode(errors="replace")
        if status != 0:
            raise SystemExit(f"exit {status}: {' '.join(argv)}\n{stderr[-3000:]}")
        return Sample(wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024, stdout)

    def _limit(self) -> None:
        if self.memory is not None:
            resource.setrlimit(resource.RLIMIT_AS, (self.memory, self.memory))

    def _wait(self, proc: subprocess.Popen[bytes]) -> tuple[int, resource.struct_rusage]:
        deadline = time.monotonic() + self.timeout
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                proc.returncode = os.waitstatus_to_exitcode(status)
                return proc.returncode, usage
            if time.monotonic() > deadline:
                os.killpg(proc.pid, 9)
            time.sleep(0.01)


# ---------------------------------------------------------------------------
# The benchmarks: each gives, per tree, the command to time
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Bench:
    """A named measurement: the argv for a tree, and how to read its output."""

    name: str
    argv: Callable[[Tree, Path], list[str]]  # (tree, a fresh scratch folder) -> argv
    cwd_tree: bool = False  # run in the tree's root (its own bench scripts)
    parts: Callable[[str], dict[str, float]] | None = None
    engine: Callable[[Sample], float] | None = None
    storm: Callable[[Path], tuple[float, str]] | None = None  # scratch -> (s, what)


def last_json(stdout: str) -> dict[str, Any]:
    """The JSON object on the last line (Storm prints warnings on stdout before it)."""
    return dict(json.loads(stdout.strip().splitlines()[-1]))


def engine_seconds(sample: Sample) -> float:
    """parse + build + check of a ``--format json`` / ``--json`` run (its timings_s)."""
    return float(sum(last_json(sample.stdout)["timings_s"].values()))


def check_bench(name: str, extra: Sequence[str], storm: bool, runner: Runner,
                work: Tree) -> Bench:
    def argv(tree: Tree, scratch: Path) -> list[str]:
        return [*tree.command(), "check", str(CASE1), *extra, "--format", "json"]

    def storm_run(scratch: Path) -> tuple[float, str]:
        folder = scratch / "emitted"
        runner.run([*work.command(), "emit", str(CASE1), *extra, "-o", str(folder)],
                   work.env())
        props = [str(p) for p in (folder / "properties.props", folder / "storm-only.props")
                 if p.exists()]
        sample = runner.run([sys.executable, "-c", STORM_CHECK, str(folder / "model.prism"),
                             *props])
        count = len(last_json(sample.stdout)["values"])
        return sample.wall, f"whole process, {count} properties"

    return Bench(name, argv, storm=storm_run if storm else None)


def model_bench(model: BenchModel, runner: Runner, storm: bool) -> Bench:
    def files(scratch: Path) -> tuple[Path, Path]:
        path, props = scratch / f"{model.family}.prism", scratch / f"{model.family}.props"
        if not path.exists():
            path.write_text(model.model)
            props.write_text(model.properties)
        return path, props

    def argv(tree: Tree, scratch: Path) -> list[str]:
        path, props = files(scratch)
        return [*tree.command(), "prism", str(path), "--props", str(props), "--json"]

    def storm_run(scratch: Path) -> tuple[float, str]:
        path, props = files(scratch)
        sample = runner.run([sys.executable, str(HERE / "run_one.py"), "storm", str(path),
                             str(props)])
        return float(last_json(sample.stdout)["total_s"]), "run_one.py: parse+build+check"

    return Bench(f"{model.family} {model.size}", argv, engine=engine_seconds,
                 storm=storm_run if storm else None)


def hm_bench(n: int) -> Bench:
    def argv(tree: Tree, scratch: Path) -> list[str]:
        path, props = scratch / f"hm{n}.prism", scratch / "hm.props"
        if not path.exists():
            text = (REPO / "tests/data/haddad_monmege.prism").read_text()
            path.write_text(text.replace("const int N;", f"const int N = {n};").replace(
                "const double p;", "const double p = 0.7;"))
            props.write_text("P=? [ F x=0 ];\n")
        return [*tree.command(), "prism", str(path), "--props", str(props), "--json"]

    return Bench(f"Haddad-Monmege N={n}", argv)


REUSE_LINE = re.compile(r"MissionChecker: ([\d.]+) s wall.*independent checks: ([\d.]+) s wall")


def reuse_bench(points: int) -> Bench:
    def argv(tree: Tree, scratch: Path) -> list[str]:
        return [sys.executable, str(tree.root / "bench" / "bench_reuse.py"), "--points",
                str(points)]

    def parts(stdout: str) -> dict[str, float]:
        found = REUSE_LINE.search(stdout)
        if found is None:
            return {}
        return {"MissionChecker s (in-process)": float(found[1]),
                "independent checks s (in-process)": float(found[2])}

    return Bench(f"bench_reuse.py --points {points}", argv, cwd_tree=True, parts=parts)


def sweep_bench(stride: int, sets: list[str], runner: Runner, work: Tree,
                storm: bool) -> Bench:
    step = Decimal(stride) / 10
    caps = [Decimal(50 + k) / 10 for k in range(0, 151, stride)]
    varies = ["--vary", f"battery.model={','.join(SWEEP_MODELS)}",
              "--vary", f"battery.capacity_ah=5:20:{step}"]
    set_args = [a for s in sets for a in ("--set", s)]

    def config(scratch: Path) -> Path:
        path = scratch / "fig6.yaml"
        path.write_text("{}\n")  # reproduce fig6 sweeps the baseline with --set strings
        return path

    def argv(tree: Tree, scratch: Path) -> list[str]:
        results = scratch / f"results-{tree.label}-{time.monotonic_ns()}.csv"
        return [*tree.command(), "sweep", str(config(scratch)), *varies, *set_args,
                "-j", "2", "-o", str(results), "--format", "csv"]

    def storm_run(scratch: Path) -> tuple[float, str]:
        folders = []
        for model in SWEEP_MODELS:
            for cap in caps:
                folder = scratch / f"emit-{model}-{cap}"
                runner.run([*work.command(), "emit", str(config(scratch)), *set_args,
                            "--set", f"battery.model={model}", "--set",
                            f"battery.capacity_ah={cap}", "-o", str(folder)], work.env())
                folders.append(str(folder))
        sample = runner.run([sys.executable, "-c", STORM_SWEEP, *folders])
        return float(last_json(sample.stdout)["total_s"]), "serial loop, P(success)"

    return Bench(f"Fig. 6 sweep, {len(caps) * 4} points, -j 2", argv,
                 storm=storm_run if storm else None)


def fig6_sets(trees: Sequence[Tree]) -> list[str]:
    """The ``--set`` strings ``reproduce fig6`` sweeps with, from the first tree that has
    ``veribattery.analyses.figures.capacity_sets``."""
    code = ("import json; from veribattery.analyses.figures import capacity_sets; "
            "print(json.dumps(list(capacity_sets(['fig6']))))")
    for tree in trees:
        proc = subprocess.run([sys.executable, "-c", code], env=tree.env(), capture_output=True,
                              text=True, check=False)
        if proc.returncode == 0:
            return list(json.loads(proc.stdout))
    raise SystemExit("no tree has veribattery.analyses.figures.capacity_sets")


# ---------------------------------------------------------------------------
# Running and reporting
# ---------------------------------------------------------------------------


def measure(bench: Bench, trees: dict[str, Tree], rounds: int, runner: Runner,
            scratch: Path) -> Row:
    """*rounds* runs per tree, alternating; Storm once after the first pair."""
    row = Row(bench.name, engine=bench.engine)
    for round_ in range(rounds):
        order = ("base", "work") if round_ % 2 == 0 else ("work", "base")
        for label in order:
            tree = trees[label]
            sample = runner.run(bench.argv(tree, scratch), tree.env(),
                                tree.root if bench.cwd_tree else scratch)
            row.samples[label].append(sample)
            for part, seconds in (bench.parts(sample.stdout) if bench.parts else {}).items():
                row.parts.setdefault(part, {"base": [], "work": []})[label].append(seconds)
        if round_ == 0 and bench.storm is not None:
            row.storm_s, row.storm_what = bench.storm(scratch)
        print(f"  {bench.name}: round {round_ + 1} done", file=sys.stderr, flush=True)
    return row


def ratio(work: float, base: float) -> str:
    return f"{work / base:.3f}" if base > 0 else "—"


def whole_table(rows: list[Row]) -> str:
    head = ("| benchmark | base wall s | work wall s | wall work/base | base CPU s | work CPU s "
            "| CPU work/base | base peak MB | work peak MB | RSS work/base |")
    lines = [head, "|" + "---|" * 10]
    for row in rows:
        b, w = row.samples["base"], row.samples["work"]
        walls = min(s.wall for s in b), min(s.wall for s in w)
        cpus = min(s.cpu for s in b), min(s.cpu for s in w)
        peaks = max(s.peak_mb for s in b), max(s.peak_mb for s in w)
        lines.append(f"| {row.name} | {walls[0]:.2f} | {walls[1]:.2f} | "
                     f"{ratio(walls[1], walls[0])} | {cpus[0]:.2f} | {cpus[1]:.2f} | "
                     f"{ratio(cpus[1], cpus[0])} | {peaks[0]:.0f} | {peaks[1]:.0f} | "
                     f"{ratio(peaks[1], peaks[0])} |")
        for part, got in row.parts.items():
            if got["base"] and got["work"]:
                pb, pw = min(got["base"]), min(got["work"])
                lines.append(f"| &nbsp;&nbsp;{part} | {pb:.2f} | {pw:.2f} | {ratio(pw, pb)} "
                             "| | | | | | |")
    return "\n".join(lines)


def storm_table(rows: list[Row]) -> str:
    lines = ["| benchmark | timed | base s | work s | Storm s | base/Storm | work/Storm |",
             "|" + "---|" * 7]
    for row in rows:
        if row.storm_s is None:
            continue
        seconds = row.engine or (lambda s: s.wall)
        timed = "engine (timings_s)" if row.engine else "whole process, wall"
        b = min(seconds(s) for s in row.samples["base"])
        w = min(seconds(s) for s in row.samples["work"])
        lines.append(f"| {row.name} | {timed}; Storm: {row.storm_what} | {b:.2f} | {w:.2f} | "
                     f"{row.storm_s:.2f} | {b / row.storm_s:.2f} | {w / row.storm_s:.2f} |")
    return "\n".join(lines)


def benches(args: argparse.Namespace, work: Tree, base: Tree, runner: Runner) -> list[Bench]:
    chosen = [b for b in args.only.split(",") if b]
    storm = not args.no_storm
    found: list[Bench] = []
    for name in chosen:
        if name == "case1":
            found.append(check_bench("check case1", (), storm, runner, work))
        elif name == "mission":
            found.append(check_bench("check 11x11 / 20 Ah", MISSION_11X11, False, runner, work))
        elif name == "models":
            found += [model_bench(m, runner, storm)
                      for m in (QUICK_MODELS if args.quick else FULL_MODELS)]
        elif name == "hm" and not args.quick:
            found += [hm_bench(n) for n in HM_SIZES]
        elif name == "reuse":
            found.append(reuse_bench(args.points or (5 if args.quick else 10)))
        elif name == "sweep":
            stride = args.stride or (75 if args.quick else 30)
            found.append(sweep_bench(stride, fig6_sets([base, work]), runner, work, storm))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n".join(__doc__.splitlines()[1:]))
    parser.add_argument("base", help="the base revision (commit, tag, branch)")
    parser.add_argument("--base-dir", type=Path, help="an existing checkout of the base to use")
    parser.add_argument("-n", "--rounds", type=int, help="runs per tree (default 2; quick 1)")
    parser.add_argument("--quick", action="store_true", help="small models, short sweeps")
    parser.add_argument("--only", default=",".join(BENCHES),
                        help=f"comma-separated benchmarks: {','.join(BENCHES)} (default all)")
    parser.add_argument("--no-storm", action="store_true", help="do not run Storm")
    parser.add_argument("--points", type=int, help="reuse points (default 10; quick 5)")
    parser.add_argument("--stride", type=int,
                        help="sweep: every K-th capacity of 5.0-20.0 Ah (default 30; quick 75)")
    parser.add_argument("--memory-gb", type=float, default=6.0,
                        help="address-space limit per process (0: none)")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds per process")
    args = parser.parse_args()
    if unknown := set(args.only.split(",")) - set(BENCHES) - {""}:
        parser.error(f"unknown benchmarks {sorted(unknown)}; choose from {BENCHES}")
    rounds = args.rounds or (1 if args.quick else 2)
    started = time.perf_counter()
    runner = Runner(args.memory_gb, args.timeout)
    work = working_tree()
    with base_tree(args.base, args.base_dir) as base, \
            tempfile.TemporaryDirectory(prefix="veribattery-speed-") as tmp:
        for tree in (base, work):
            tree.compile()
        note_differing_benches(base)
        load = os.getloadavg()[0]
        rows: list[Row] = []
        for bench in benches(args, work, base, runner):
            scratch = Path(tmp) / f"bench{len(rows)}"
            scratch.mkdir()
            rows.append(measure(bench, {"base": base, "work": work}, rounds, runner, scratch))
    print(f"base {args.base} ({base.revision}) against the working tree ({work.revision}); "
          f"{rounds} round(s) each, alternating; min wall and CPU, max peak RSS; "
          f"load average {load:.1f} at the start, {os.getloadavg()[0]:.1f} at the end\n")
    print(whole_table(rows))
    if any(r.storm_s is not None for r in rows):
        print("\nAgainst Storm (measured once, in the same run):\n")
        print(storm_table(rows))
    print(f"\n(compare_speed.py took {time.perf_counter() - started:.0f} s)")


def note_differing_benches(base: Tree) -> None:
    """Say when a bench script that each tree runs from its own copy differs between them."""
    for script in ("bench/bench_reuse.py",):
        mine, theirs = REPO / script, base.root / script
        if not theirs.exists() or mine.read_bytes() != theirs.read_bytes():
            print(f"note: {script} differs between the trees; each tree runs its own",
                  flush=True)


if __name__ == "__main__":
    main()
