"""Whole-process cost of veribattery against Storm, and where the start-up goes.

Each command runs as a fresh process, veribattery and Storm (stormpy: parse, build,
check in one process) alternating, ``--rounds`` times; CPU is user + system of the
child (``os.wait4``), wall is ``perf_counter`` around it, RSS the child's peak. With
``--before SRC`` the same veribattery commands also run from another source tree (e.g.
``git archive main src | tar -x -C /tmp/before``, compiled with ``compileall``) in the
same rounds, so before and after see the same machine load.

    python bench/bench_startup.py                       # tiny model and case1, 5 rounds
    python bench/bench_startup.py --before /tmp/before/src --rounds 7
    python bench/bench_startup.py --imports             # -X importtime table of the tiny run

Timing on a shared machine is noisy: compare within a row, and prefer CPU minima.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
VERIBATTERY = Path(sys.executable).with_name("veribattery")

TINY = """dtmc
module m
 x : [0..2] init 0;
 [] x=0 -> 0.5:(x'=1) + 0.5:(x'=2);
 [] x>0 -> true;
endmodule
"""
TINY_PROPS = "P=? [ F x=1 ]\n"
PAPER_PROPS = """"p_success": P=? [ F "success" ];
"exp_mission_time": R{"mt"}=? [ F "done" ];
"exp_recharges": R{"rc"}=? [ F "done" ];
"""
STORM = """import sys, stormpy
prog = stormpy.parse_prism_program(sys.argv[1])
props = stormpy.parse_properties(open(sys.argv[2]).read(), prog)
model = stormpy.build_model(prog, props)
init = model.initial_states[0]
print(model.nr_states, [stormpy.model_checking(model, p).get_value(init) for p in props])
"""
#: Modules whose cumulative import time ``--imports`` reports (those present).
IMPORT_ROWS = (
    "click", "veribattery.cli", "numpy", "scipy.sparse",
    "scipy.sparse.linalg", "scipy.linalg", "numpy.ma", "veribattery.lang",
    "veribattery.lang.nodes", "veribattery.explore", "veribattery.checker",
    "veribattery.pipeline", "rich", "pydantic", "yaml", "jinja2", "lark",
)


def run(argv: Sequence[str], env: dict[str, str] | None = None) -> tuple[float, float, int]:
    """Wall s, CPU s (user + sys) and peak RSS KB of one process."""
    start = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode not in (0, 1):
        err = proc.stderr.read().decode() if proc.stderr else ""
        raise SystemExit(f"{' '.join(argv)}: exit {proc.returncode}\n{err}")
    if proc.stderr:
        proc.stderr.close()
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss


def cases(work: Path) -> dict[str, tuple[list[str], list[str] | None]]:
    """Name -> (veribattery argv tail, Storm argv or None)."""
    (work / "tiny.prism").write_text(TINY)
    (work / "tiny.props").write_text(TINY_PROPS)
    subprocess.run([str(VERIBATTERY), "emit", str(REPO / "configs/paper/case1.yaml"),
                    "-o", str(work / "case1")], check=True, capture_output=True)
    (work / "case1/paper.props").write_text(PAPER_PROPS)
    storm = [sys.executable, str(work / "storm.py")]
    (work / "storm.py").write_text(STORM)
    tiny, case1 = work / "tiny", work / "case1"
    return {
        "tiny `prism --props` (table)": (
            ["prism", f"{tiny}.prism", "--props", f"{tiny}.props"],
            [*storm, f"{tiny}.prism", f"{tiny}.props"]),
        "tiny `prism --props --json`": (
            ["prism", f"{tiny}.prism", "--props", f"{tiny}.props", "--json"], None),
        "case1 `prism --props paper.props` (3)": (
            ["prism", f"{case1}/model.prism", "--props", f"{case1}/paper.props"],
            [*storm, f"{case1}/model.prism", f"{case1}/paper.props"]),
        "case1 `check` (5) / Storm properties.props (5)": (
            ["check", str(REPO / "configs/paper/case1.yaml")],
            [*storm, f"{case1}/model.prism", f"{case1}/properties.props"]),
    }


def summary(samples: list[tuple[float, float, int]]) -> str:
    walls, cpus, rss = zip(*samples, strict=True)
    return (f"{min(walls):.2f} / {statistics.median(walls):.2f} s wall, "
            f"{min(cpus):.2f} / {statistics.median(cpus):.2f} s CPU, {max(rss) // 1024} MB")


def timing_table(rounds: int, before: Path | None, only: str | None) -> None:
    env_before = None
    if before is not None:
        env_before = {**os.environ, "PYTHONPATH": str(before)}
    with tempfile.TemporaryDirectory() as tmp:
        rows = [(name, c) for name, c in cases(Path(tmp)).items() if not only or only in name]
        print("| run (min / median of", rounds, "rounds) | veribattery | before | Storm |")
        print("|---|---|---|---|")
        for name, (tail, storm) in rows:
            got: dict[str, list[tuple[float, float, int]]] = {"vb": [], "before": [], "storm": []}
            for _ in range(rounds):
                got["vb"].append(run([str(VERIBATTERY), *tail]))
                if env_before is not None:
                    got["before"].append(run([str(VERIBATTERY), *tail], env_before))
                if storm is not None:
                    got["storm"].append(run(storm))
            cells = [summary(got[k]) if got[k] else "—" for k in ("vb", "before", "storm")]
            print(f"| {name} | {' | '.join(cells)} |", flush=True)


def import_table(rounds: int, before: Path | None) -> None:
    """Minimum cumulative ``-X importtime`` per module of the tiny ``--json`` run."""
    code = ("from veribattery.cli import main\ntry:\n    main(['prism', {m!r}, '--property', "
            "'P=? [ F x=1 ]', '--json'])\nexcept SystemExit:\n    pass\n")
    trees = {"after": None, "before": before} if before else {"after": None}
    with tempfile.TemporaryDirectory() as tmp:
        model = Path(tmp) / "tiny.prism"
        model.write_text(TINY)
        best: dict[str, dict[str, int]] = {tree: {} for tree in trees}
        for _ in range(rounds):
            for tree, src in trees.items():
                env = {**os.environ, **({"PYTHONPATH": str(src)} if src else {})}
                err = subprocess.run([sys.executable, "-X", "importtime", "-c",
                                      code.format(m=str(model))], env=env, check=True,
                                     capture_output=True, text=True).stderr
                for name, us in _cumulative(err).items():
                    best[tree][name] = min(best[tree].get(name, us), us)
    print("| module (cumulative ms, min of", rounds, ") |", " | ".join(trees), "|")
    print("|---|" + "---|" * len(trees))
    for name in (*IMPORT_ROWS, "<all imports>"):
        cells = [f"{best[t][name] / 1000:.1f}" if name in best[t] else "not imported"
                 for t in trees]
        print(f"| {name} | {' | '.join(cells)} |")


def _cumulative(importtime: str) -> dict[str, int]:
    found, total = {}, 0
    for line in importtime.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _, cumulative, name = line.split("|")
        found[name.strip()] = int(cumulative)
        if not name.startswith("  "):  # a top-level import: its own and its children's
            total += int(cumulative)
    found["<all imports>"] = total
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--before", type=Path, help="another src/ tree to time alongside")
    parser.add_argument("--only", help="run only the cases whose name contains this")
    parser.add_argument("--imports", action="store_true", help="the -X importtime table")
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f}")
    if args.imports:
        import_table(args.rounds, args.before)
    else:
        timing_table(args.rounds, args.before, args.only)
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
