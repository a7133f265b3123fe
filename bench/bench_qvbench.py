"""veribattery against Storm on the DTMCs of the Quantitative Verification Benchmark Set.

The models are not copied here: point ``--root`` at a checkout of the QVBench
repository (https://github.com/ahartmanns/qcomp, folder ``benchmarks/dtmc``).
Each instance runs ``veribattery prism --json`` and a stormpy script (default
engine, float) in fresh processes, one after the other, and prints per property
our value, our certified interval, Storm's value, and whether Storm's value lies
in our interval (Storm's default engine stops at 1e-6 relative, so "outside"
there is Storm's error more often than ours), with CPU seconds and peak RSS of
both processes. Storm builds the model with its properties, so its state count
can be smaller: it makes the states that decide a single formula absorbing.

    python bench/bench_qvbench.py --root ~/qcomp/benchmarks/dtmc [--only herman]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_scale import byte_compile_sources

#: (model file, properties file, constants): the smaller published instances.
INSTANCES: list[tuple[str, str, dict[str, object]]] = [
    ("brp/brp.prism", "brp/brp.props", {"N": 64, "MAX": 5}),
    ("crowds/crowds.prism", "crowds/crowds.props", {"TotalRuns": 5, "CrowdSize": 10}),
    ("egl/egl.prism", "egl/egl.props", {"N": 5, "L": 8}),
    ("haddad-monmege/haddad-monmege.pm", "haddad-monmege/haddad-monmege.prctl",
     {"N": 300, "p": 0.7}),
    ("herman/herman.13.prism", "herman/herman.props", {}),
    ("herman/herman.15.prism", "herman/herman.props", {}),
    ("leader_sync/leader_sync.5-4.prism", "leader_sync/leader_sync.props", {}),
    ("nand/nand.prism", "nand/nand.props", {"N": 20, "K": 4}),
    ("oscillators/oscillators.6-10-0.1-1.prism", "oscillators/oscillators.props",
     {"mu": 0.1, "lambda": 1.0}),
]

STORM_SCRIPT = """
import json, sys, stormpy
prog = stormpy.parse_prism_program(sys.argv[1])
props = stormpy.parse_properties(open(sys.argv[2]).read(), prog)
model = stormpy.build_model(prog, props)
values = []
for prop in props:
    result = stormpy.model_checking(model, prop)
    if result.is_qualitative():
        values.append(None)
        continue
    vector = result.get_value_vector()
    found = [float(vector[s]) for s in model.initial_states]
    # Several initial states: the range (our filters report one end of it).
    values.append(found[0] if len(found) == 1 else [min(found), max(found)])
print(json.dumps({"states": model.nr_states, "values": values}))
"""


def with_constants(model: Path, constants: dict[str, object], folder: Path) -> Path:
    """A copy of *model* with its open constants defined (for Storm)."""
    text = model.read_text()
    for name, value in constants.items():
        text = re.sub(rf"const\s+(int|double)\s+{re.escape(name)}\s*;",
                      rf"const \1 {name} = {value};", text)
    path = folder / model.name
    path.write_text(text)
    return path


def timed(command: list[str], timeout: float) -> tuple[str, float, float]:
    """stdout, user CPU seconds and peak RSS (MB) of *command* in a fresh process
    (GNU time reports them: ``getrusage`` of children only keeps the largest peak)."""
    with tempfile.NamedTemporaryFile("r", suffix=".time") as report:
        try:
            done = subprocess.run(["/usr/bin/time", "-o", report.name, "-f", "%U %M", *command],
                                  capture_output=True, text=True, timeout=timeout, check=False)
            out = done.stdout
        except subprocess.TimeoutExpired:
            return "", timeout, float("nan")
        cpu, peak_kb = Path(report.name).read_text().split()[-2:]
    return out, float(cpu), float(peak_kb) / 1024


def run(root: Path, instance: tuple[str, str, dict[str, object]], timeout: float) -> None:
    model_name, props_name, constants = instance
    model, props = root / model_name, root / props_name
    exe = str(Path(sys.executable).parent / "veribattery")
    consts = [arg for k, v in constants.items() for arg in ("--const", f"{k}={v}")]
    ours_out, ours_cpu, ours_mb = timed(
        [exe, "prism", str(model), "--props", str(props), "--json", *consts], timeout)
    with tempfile.TemporaryDirectory() as tmp:
        storm_out, storm_cpu, storm_mb = timed(
            [sys.executable, "-c", STORM_SCRIPT, str(with_constants(model, constants, Path(tmp))),
             str(props)], timeout)
    ours = json.loads(ours_out) if ours_out else {"model": {}, "results": []}
    storm = json.loads(storm_out.strip().splitlines()[-1]) if storm_out.strip() else {}
    print(f"{model_name} {constants}: states {ours['model'].get('states')} "
          f"(Storm {storm.get('states', 'timeout')}); CPU {ours_cpu:.1f} s vs {storm_cpu:.1f} s; "
          f"peak {ours_mb:.0f} vs {storm_mb:.0f} MB")
    storm_values = storm.get("values", [])
    for k, result in enumerate(ours["results"]):
        theirs = storm_values[k] if k < len(storm_values) else None
        bounds = result.get("bounds")
        inside = ""
        ends = theirs if isinstance(theirs, list) else [theirs]
        if bounds and all(isinstance(b, float) for b in [*bounds, *ends]):
            inside = ("inside" if any(bounds[0] <= e <= bounds[1] for e in ends)
                      else "outside")
        print(f"  {result.get('name') or result['property']}: {result['value']} "
              f"{bounds or ''} | Storm {theirs} {inside}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, required=True,
                        help="the QVBench folder benchmarks/dtmc")
    parser.add_argument("--only", default="", help="run instances whose file contains this")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds per process")
    args = parser.parse_args()
    byte_compile_sources()
    for instance in INSTANCES:
        if args.only in instance[0]:
            run(args.root, instance, args.timeout)


if __name__ == "__main__":
    main()
