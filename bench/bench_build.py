"""The state-space builder alone against Storm's parse + build, same run, fresh process each.

    python bench/bench_build.py [--big] [--repeat N]

Each measurement runs in its own subprocess, so its peak RSS is the builder's own
(imports included: about 80 MB for veribattery, 90 MB for stormpy). Times are CPU
seconds of the parse + build (``time.process_time``), which a machine shared with
other jobs inflates less than wall-clock time; wall seconds are printed beside
them. Models: the mission (case1, and the 215,523-state advanced-battery point),
the 10^6-state grid walk and synchronised counters of ``bench_models``, and with
``--big`` the 1.4M-state mission at 11x11 turbines / 20 Ah. Prints a markdown table.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from models import counters, grid_walk

VB_SCRIPT = """
import json, resource, sys, time
from veribattery.explore import build_dtmc
from veribattery.lang import parse_model
from veribattery.pipeline import flatten_model
cpu, wall = time.process_time(), time.perf_counter()
dtmc = build_dtmc(flatten_model(parse_model(open(sys.argv[1]).read()), {}))
print(json.dumps({"states": dtmc.num_states, "transitions": dtmc.num_transitions,
                  "cpu": time.process_time() - cpu, "wall": time.perf_counter() - wall,
                  "peak": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""

STORM_SCRIPT = """
import json, resource, sys, time
import stormpy
cpu, wall = time.process_time(), time.perf_counter()
program = stormpy.parse_prism_program(sys.argv[1])
model = stormpy.build_model(program)  # every label and reward structure, as ours
print(json.dumps({"states": model.nr_states, "transitions": model.nr_transitions,
                  "cpu": time.process_time() - cpu, "wall": time.perf_counter() - wall,
                  "peak": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""

MISSIONS = {
    "case1": [],
    "advanced 12.8 Ah": ["--set", "battery.model=advanced", "--set", "battery.capacity_ah=12.8"],
}
BIG = {
    "11x11, 20 Ah": ["--set", "farm.cols=11", "--set", "farm.rows=11", "--set", "farm.base=[5,5]",
                     "--set", "battery.capacity_ah=20"],
}
HEADER = ["model", "size", "states", "transitions", "vb build CPU s", "vb wall s", "vb peak MB",
          "storm build CPU s", "storm wall s", "storm peak MB", "CPU ratio vb/storm"]


def measure(script: str, model: Path) -> dict[str, float]:
    out = subprocess.run([sys.executable, "-c", script, str(model)], check=True,
                         capture_output=True, text=True).stdout
    return dict(json.loads(out.strip().splitlines()[-1]))


def emit(options: list[str], workdir: Path, name: str) -> Path:
    exe = str(Path(sys.executable).parent / "veribattery")
    target = workdir / name.replace(" ", "_").replace(",", "")
    subprocess.run([exe, "emit", "configs/paper/case1.yaml", *options, "-o", str(target)],
                   check=True, capture_output=True)
    return target / "model.prism"


def row(family: str, size: str, model: Path, repeat: int) -> list[str]:
    """The best (least CPU) of *repeat* runs of each tool, back to back."""
    runs = [(measure(VB_SCRIPT, model), measure(STORM_SCRIPT, model)) for _ in range(repeat)]
    vb = min((r[0] for r in runs), key=lambda r: r["cpu"])
    storm = min((r[1] for r in runs), key=lambda r: r["cpu"])
    if (vb["states"], vb["transitions"]) != (storm["states"], storm["transitions"]):
        raise SystemExit(f"{family} {size}: state spaces differ: {vb} vs {storm}")
    return [family, size, f"{int(vb['states']):,}", f"{int(vb['transitions']):,}",
            f"{vb['cpu']:.2f}", f"{vb['wall']:.2f}", f"{vb['peak']:.0f}",
            f"{storm['cpu']:.2f}", f"{storm['wall']:.2f}", f"{storm['peak']:.0f}",
            f"{vb['cpu'] / storm['cpu']:.2f}"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--big", action="store_true", help="add the 1.4M-state mission")
    parser.add_argument("--repeat", type=int, default=2, help="runs per tool (best kept)")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        missions = {**MISSIONS, **(BIG if args.big else {})}
        for name, options in missions.items():
            rows.append(row("mission", name, emit(options, workdir, name), args.repeat))
        for bench in (grid_walk(1000), counters(4, 31)):
            path = workdir / f"{bench.family}.prism"
            path.write_text(bench.model)
            rows.append(row(bench.family, bench.size, path, args.repeat))
    print("| " + " | ".join(HEADER) + " |")
    print("|" + "---|" * len(HEADER))
    for cells in rows:
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
