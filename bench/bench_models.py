"""Benchmark veribattery against Storm (stormpy), side by side in one run.

Each measurement runs in a fresh subprocess (bench/run_one.py), so peak memory is
the tool's own. Prints the tables and writes them where the performance page of the
documentation includes them (docs/_bench/), replacing the previous run's figures.

    python bench/bench_models.py            # the full tables (10^4 .. 10^6 states)
    python bench/bench_models.py --quick    # small sizes only, nothing written
    python bench/bench_models.py --hm-only  # only the Haddad-Monmege table
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from models import BenchModel, counters, grid_walk

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
#: The tables the performance page (docs/performance.md) includes.
MODELS_TABLE = REPO / "docs" / "_bench" / "bench_models.md"
HM_TABLE = REPO / "docs" / "_bench" / "haddad_monmege.md"

FULL = [
    grid_walk(100), grid_walk(316), grid_walk(448), grid_walk(1000),
    counters(3, 58), counters(4, 31),
]
QUICK = [grid_walk(100), counters(3, 20)]
HM_SIZES = (20, 100, 300)


def measure(tool: str, model: Path, props: Path) -> dict[str, object]:
    """One tool on one model file, in its own process."""
    proc = subprocess.run(
        [sys.executable, str(HERE / "run_one.py"), tool, str(model), str(props)],
        capture_output=True, text=True, check=False,
    )
    if proc.returncode != 0:
        raise SystemExit(f"{tool} failed on {model}:\n{proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def agree(a: list[object], b: list[object]) -> bool:
    """Values equal within 1e-6 relative (Storm's default solver precision)."""
    return all(
        math.isclose(float(x), float(y), rel_tol=1e-6, abs_tol=1e-12)  # type: ignore[arg-type]
        for x, y in zip(a, b, strict=True)
    )


def bench_model(bench: BenchModel, workdir: Path) -> list[str]:
    """A table row for one model instance."""
    model = workdir / f"{bench.family}.prism"
    props = workdir / f"{bench.family}.props"
    model.write_text(bench.model)
    props.write_text(bench.properties)
    ours = measure("veribattery", model, props)
    storm = measure("storm", model, props)
    ratio = float(ours["total_s"]) / float(storm["total_s"])  # type: ignore[arg-type]
    assert ours["states"] == storm["states"], (ours["states"], storm["states"])
    return [
        bench.family, bench.size, f"{ours['states']:,}", f"{ours['transitions']:,}",
        f"{ours['build_s']:.2f}", f"{ours['check_s']:.2f}",
        f"{storm['build_s']:.2f}", f"{storm['check_s']:.2f}", f"{ratio:.2f}",
        f"{ours['peak_rss_mb']:.0f}", f"{storm['peak_rss_mb']:.0f}",
        "yes" if agree(ours["values"], storm["values"]) else "NO",  # type: ignore[arg-type]
    ]


def whole_process(argv: list[str]) -> tuple[float, float]:
    """Wall-clock seconds and peak RSS (MB) of a whole command, start-up included."""
    start = time.perf_counter()
    proc = subprocess.run(["/usr/bin/time", "-f", "%M", *argv], check=True,
                          capture_output=True, text=True)
    return time.perf_counter() - start, int(proc.stderr.strip().splitlines()[-1]) / 1024


STORM_SCRIPT = """
import sys, stormpy
prog = stormpy.parse_prism_program(sys.argv[1])
props = stormpy.parse_properties(open(sys.argv[2]).read(), prog)
model = stormpy.build_model(prog, props)
init = model.initial_states[0]
print(model.nr_states, [stormpy.model_checking(model, p).get_value(init) for p in props])
"""


def bench_mission(config: str, workdir: Path) -> list[str]:
    """`veribattery check CONFIG` against Storm on the emitted files, whole process each."""
    exe = str(Path(sys.executable).parent / "veribattery")
    emitted = workdir / "mission"
    subprocess.run([exe, "emit", config, "-o", str(emitted)], check=True, capture_output=True)
    ours, our_mb = whole_process([exe, "check", config, "--format", "json"])
    storm, storm_mb = whole_process([sys.executable, "-c", STORM_SCRIPT,
                                     str(emitted / "model.prism"),
                                     str(emitted / "properties.props")])
    return ["mission", Path(config).stem, "", "", "", f"{ours:.2f} (whole)", "",
            f"{storm:.2f} (whole)", f"{ours / storm:.2f}", f"{our_mb:.0f}", f"{storm_mb:.0f}", ""]


def haddad_monmege(n: int) -> str:
    """Haddad & Monmege's chain with N and p = 0.7 fixed: ``P=? [F x=0]`` is exactly 0.7."""
    text = (REPO / "tests/data/haddad_monmege.prism").read_text()
    return text.replace("const int N;", f"const int N = {n};").replace(
        "const double p;", "const double p = 0.7;")


STORM_MODE_SCRIPT = """
import json, resource, sys, time, stormpy
mode = sys.argv[3]
start = time.perf_counter()
prog = stormpy.parse_prism_program(sys.argv[1])
props = stormpy.parse_properties(open(sys.argv[2]).read(), prog)
exact = mode == "exact"
model = stormpy.build_model[stormpy.Rational if exact else float](prog, props)
env = {"default": stormpy.Environment, "sound": stormpy.environments.sound,
       "exact": stormpy.environments.exact}[mode]()
value = stormpy.model_checking(model, props[0], environment=env).get_value(
    model.initial_states[0])
print(json.dumps({"value": str(value), "total_s": time.perf_counter() - start,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""

#: Storm's sound mode does not finish on HM(100) in minutes (issue 9): cap each run.
STORM_TIMEOUT_S = 120


def storm_mode(model: Path, props: Path, mode: str) -> str:
    """``value / seconds / peak MB`` of Storm in *mode*, or the timeout."""
    try:
        proc = subprocess.run([sys.executable, "-c", STORM_MODE_SCRIPT, str(model), str(props),
                               mode], capture_output=True, text=True, check=True,
                              timeout=STORM_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return f"timeout > {STORM_TIMEOUT_S} s"
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    return f"{out['value']} / {out['total_s']:.2f} s / {out['peak_rss_mb']:.0f} MB"


HM_HEADER = ["N", "states", "vb value [lower, upper]", "vb whole s", "vb peak MB",
             "storm default", "storm sound", "storm exact"]


def bench_haddad_monmege(n: int, workdir: Path) -> list[str]:
    """One row of the Haddad-Monmege table: ours (certified) and Storm's three modes."""
    model, props = workdir / f"hm{n}.prism", workdir / f"hm{n}.props"
    model.write_text(haddad_monmege(n))
    props.write_text("P=? [ F x=0 ];\n")
    exe = str(Path(sys.executable).parent / "veribattery")
    start = time.perf_counter()
    proc = subprocess.run(["/usr/bin/time", "-f", "%M", exe, "prism", str(model), "--props",
                           str(props), "--json"], capture_output=True, text=True, check=True)
    whole = time.perf_counter() - start
    doc = json.loads(proc.stdout)
    result = doc["results"][0]
    peak_mb = int(proc.stderr.strip().splitlines()[-1]) / 1024
    return [str(n), f"{doc['model']['states']:,}",
            f"{result['value']!r} [{result['bounds'][0]!r}, {result['bounds'][1]!r}]",
            f"{whole:.2f}", f"{peak_mb:.0f}",
            *(storm_mode(model, props, mode) for mode in ("default", "sound", "exact"))]


HEADER = ["model", "size", "states", "transitions", "vb build s", "vb check s",
          "storm build s", "storm check s", "ratio vb/storm", "vb peak MB", "storm peak MB",
          "agree"]


def markdown(rows: list[list[str]], header: list[str] = HEADER) -> str:
    """The table as GitHub markdown."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def command() -> str:
    """This run's command line, as the reader would type it."""
    return " ".join(["python bench/bench_models.py", *sys.argv[1:]])


def provenance(made_by: str) -> str:
    """The line that heads a written table: what made it, when, at what load."""
    return (f"Generated by `{made_by}` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
            f" at load average {os.getloadavg()[0]:.1f}; times are wall-clock seconds.\n\n")


def write_table(path: Path, made_by: str, table: str) -> None:
    """Replace *path* with *table* under its provenance line."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(provenance(made_by) + table, encoding="utf-8")
    print(f"wrote {path.relative_to(REPO)}", file=sys.stderr)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="small models only, nothing written")
    parser.add_argument("--no-mission", action="store_true", help="skip the mission baseline")
    parser.add_argument("--hm-only", action="store_true",
                        help="only the Haddad-Monmege table")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        hm_rows = [bench_haddad_monmege(n, Path(tmp)) for n in HM_SIZES]
    hm_table = markdown(hm_rows, HM_HEADER)
    print(hm_table)
    if not args.quick:
        write_table(HM_TABLE, command(), hm_table)
    if args.hm_only:
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for bench in QUICK if args.quick else FULL:
            rows.append(bench_model(bench, Path(tmp)))
            print(" | ".join(rows[-1]), flush=True)
        if not args.no_mission:
            rows.append(bench_mission(str(REPO / "configs/paper/case1.yaml"), Path(tmp)))
    table = markdown(rows)
    print(table)
    if not args.quick:
        write_table(MODELS_TABLE, command(), table)


if __name__ == "__main__":
    main()
