"""veribattery against Storm on the QComp DTMCs of 10^6 to 10^7 states, in one run.

Each instance runs ``veribattery prism MODEL --props FILE --property P --const ...
--json`` and a stormpy script (default engine and environment -- Storm's sound one,
precision 1e-6 relative -- float; the model built for that one property, as Storm
does) in fresh processes, one after the other, each under a wall-clock timeout and
an address-space cap (``ulimit -v``). It reports states, our value and certified
interval, Storm's value and whether it lies inside our interval, the reference value
from QComp's property files where there is one, whole-process wall time and peak RSS
of both and the ratios, as a markdown table (rewritten after every instance, so a
stopped run keeps what it measured).

The models are vendored in ``bench/qcomp/`` (CC-BY 4.0, origin in its README;
``bench/fetch_qcomp.sh`` refreshes them). brp and egl have no published instance
in this range: larger constants of the same models are run and marked so.

    python bench/bench_scale.py [--only nand] [--timeout 900] [--memory-gb 12]
        [--out docs/_bench/scale.md]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
MODELS = HERE / "qcomp"


@dataclass(frozen=True)
class Instance:
    """One model, one property, one set of constants."""

    model: str
    props: str
    prop: str
    constants: dict[str, int] = field(default_factory=dict)
    #: Storm's exact result as recorded in QComp's ``index.json`` (the ``// RESULT``
    #: comments of the property files are rounded: crowds's differ in the 8th digit).
    reference: float | None = None
    published: bool = True

    @property
    def label(self) -> str:
        consts = " ".join(f"{k}={v}" for k, v in self.constants.items())
        name = Path(self.model).stem
        return f"{name} {consts}".strip() + ("" if self.published else " (scaled)")


NAND, NAND_PROPS = "nand/nand.prism", "nand/nand.props"

#: Ordered from quick to slow.
INSTANCES: list[Instance] = [
    Instance(NAND, NAND_PROPS, "reliable", {"N": 40, "K": 1}, 0.2864873082856141),
    Instance(NAND, NAND_PROPS, "reliable", {"N": 40, "K": 2}, 0.483805479851772),
    Instance(NAND, NAND_PROPS, "reliable", {"N": 40, "K": 3}, 0.577706913883102),
    Instance(NAND, NAND_PROPS, "reliable", {"N": 40, "K": 4}, 0.6186822208152001),
    Instance(NAND, NAND_PROPS, "reliable", {"N": 60, "K": 1}, 0.2694609918038636),
    Instance("crowds/crowds.prism", "crowds/crowds.props", "positive",
             {"TotalRuns": 5, "CrowdSize": 20}, 0.08606905443651044),
    Instance("crowds/crowds.prism", "crowds/crowds.props", "positive",
             {"TotalRuns": 6, "CrowdSize": 15}, 0.12865369542143604),
    Instance("brp/brp.prism", "brp/brp.props", "p1", {"N": 16384, "MAX": 10}, None, False),
    # The largest published crowds (10,291,282 states by Storm's count, which makes
    # decided states absorbing); QComp records no exact value for it.
    Instance("crowds/crowds.prism", "crowds/crowds.props", "positive",
             {"TotalRuns": 6, "CrowdSize": 20}),
    Instance("egl/egl.prism", "egl/egl.props", "unfairA", {"N": 7, "L": 8}, None, False),
    Instance(NAND, NAND_PROPS, "reliable", {"N": 60, "K": 2}, 0.5175335545543008),
    # Herman's ring of N has 2^N states but 3^N + 1 transitions (a state with k tokens
    # has 2^k successors): 1.3e8 at N=17, 1.2e9 at N=19, 1.0e10 at N=21, beyond any
    # explicit engine on 24 GB from N=19 on.
    Instance("herman/herman.17.prism", "herman/herman.props", "steps"),
]

STORM_SCRIPT = """
import json, sys, stormpy
prog = stormpy.parse_prism_program(sys.argv[1])
props = [p for p in stormpy.parse_properties(open(sys.argv[2]).read(), prog)
         if p.get_name() == sys.argv[3]]
model = stormpy.build_model(prog, props)
result = stormpy.model_checking(model, props[0])
vector = result.get_value_vector()
found = [float(vector[s]) for s in model.initial_states]
# Several initial states: the range (a filter or our report picks one end of it).
print(json.dumps({"states": model.nr_states, "transitions": model.nr_transitions,
                  "values": [min(found), max(found)]}))
"""


@dataclass
class Measured:
    """What one process printed (its last JSON line), its wall time and peak RSS."""

    output: dict[str, object] | None
    wall_s: float
    peak_mb: float
    failure: str = ""


def with_constants(model: Path, constants: dict[str, int], folder: Path) -> Path:
    """A copy of *model* with its open constants defined (stormpy takes no -const)."""
    text = model.read_text()
    for name, value in constants.items():
        text = re.sub(rf"const\s+(int|double)\s+{re.escape(name)}\s*;",
                      rf"const \1 {name} = {value};", text)
    path = folder / model.name
    path.write_text(text)
    return path


def byte_compile_sources() -> None:
    """Byte-compile src/ as ``make bytecode`` (and a wheel install) does, before anything
    is timed: with PYTHONDONTWRITEBYTECODE set, a module edited since its last compile is
    compiled again in every process, start-up a user's installation does not pay."""
    subprocess.run([sys.executable, "-m", "compileall", "-q",
                    str(Path(__file__).resolve().parent.parent / "src")],
                   check=True, stdout=subprocess.DEVNULL)


def measured(command: list[str], timeout: float, memory_kb: int) -> Measured:
    """Run *command* in a fresh process group under ``ulimit -v memory_kb`` and GNU time."""
    with tempfile.NamedTemporaryFile("r", suffix=".time") as report:
        shell = 'ulimit -v "$1"; shift; exec /usr/bin/time -o "$0" -f "%e %M" "$@"'
        start = time.perf_counter()
        process = subprocess.Popen(["bash", "-c", shell, report.name, str(memory_kb), *command],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   start_new_session=True)
        try:
            out, err = process.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)  # the group this run started
            process.communicate()
            return Measured(None, time.perf_counter() - start, math.nan, f"timeout {timeout:.0f} s")
        fields = Path(report.name).read_text().split()
    wall, peak_kb = (float(fields[-2]), float(fields[-1])) if len(fields) >= 2 else (math.nan,
                                                                                      math.nan)
    lines = [line for line in out.splitlines() if line.startswith("{")]
    if process.returncode != 0 or not lines:
        reason = (err.strip().splitlines() or [f"exit {process.returncode}"])[-1]
        return Measured(None, wall, peak_kb / 1024, reason[:120])
    return Measured(json.loads(lines[-1]), wall, peak_kb / 1024)


def run_ours(instance: Instance, timeout: float, memory_kb: int) -> Measured:
    exe = str(Path(sys.executable).parent / "veribattery")
    consts = [arg for k, v in instance.constants.items() for arg in ("--const", f"{k}={v}")]
    return measured([exe, "prism", str(MODELS / instance.model), "--props",
                     str(MODELS / instance.props), "--property", instance.prop, *consts,
                     "--json"], timeout, memory_kb)


def run_storm(instance: Instance, timeout: float, memory_kb: int) -> Measured:
    with tempfile.TemporaryDirectory() as tmp:
        model = with_constants(MODELS / instance.model, instance.constants, Path(tmp))
        return measured([sys.executable, "-c", STORM_SCRIPT, str(model),
                         str(MODELS / instance.props), instance.prop], timeout, memory_kb)


def _number(value: object) -> float | None:
    return float(value) if isinstance(value, (int, float)) else None


def row(instance: Instance, ours: Measured, storm: Measured) -> str:
    """One markdown table row."""
    result = (ours.output or {}).get("results", [{}])[0] if ours.output else {}
    assert isinstance(result, dict)
    model = ours.output.get("model", {}) if ours.output else {}
    assert isinstance(model, dict)
    bounds = result.get("bounds")
    value = _number(result.get("value"))
    storm_values = (storm.output or {}).get("values") or []
    assert isinstance(storm_values, list)
    ends = [_number(v) for v in storm_values]
    if bounds and value is not None and all(e is not None for e in ends) and ends:
        # The end of Storm's range over the initial states nearer to our value.
        ends.sort(key=lambda e: abs(e - value))  # type: ignore[operator]
    theirs = ends[0] if ends else None
    inside = ""
    if isinstance(bounds, list) and theirs is not None:
        inside = "yes" if bounds[0] <= theirs <= bounds[1] else "**no**"
    ours_cell = f"{value:.12g} [{bounds[0]:.12g}, {bounds[1]:.12g}]" if (
        value is not None and isinstance(bounds, list)) else (ours.failure or "-")
    storm_cell = f"{theirs:.12g}" if theirs is not None else (storm.failure or "-")
    reference = f"{instance.reference:.12g}" if instance.reference is not None else ""
    time_ratio = ours.wall_s / storm.wall_s if ours.output and storm.output else math.nan
    rss_ratio = ours.peak_mb / storm.peak_mb if ours.output and storm.output else math.nan
    states = model.get("states", "")
    storm_states = (storm.output or {}).get("states", "")
    return (f"| {instance.label} | {states} | {storm_states} | {ours_cell} | {storm_cell} "
            f"| {inside} | {reference} | {ours.wall_s:.1f} | {storm.wall_s:.1f} "
            f"| {ratio_cell(time_ratio, ours)} | {ours.peak_mb:.0f} | {storm.peak_mb:.0f} "
            f"| {ratio_cell(rss_ratio, ours)} |")


def ratio_cell(ratio: float, ours: Measured) -> str:
    """A ratio for the table: two decimals, '-' without one, or our failure."""
    if math.isnan(ratio):
        return "-" if ours.output else "(ours failed)"
    return f"{ratio:.2f}"


HEADER = (
    "| instance | states | Storm states | veribattery value [certified interval] "
    "| Storm value | Storm inside | QComp exact | ours s | Storm s | time ratio "
    "| ours MB | Storm MB | RSS ratio |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
)


def write(out: Path, rows: list[str], settings: str) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(
        "# Scale: veribattery and Storm on QComp DTMCs of 10^6 to 10^7 states\n\n"
        "Generated by `bench/bench_scale.py` (do not edit by hand). Whole-process wall "
        "time and peak RSS of `veribattery prism ... --json` and of a stormpy script "
        "(default engine, float, the model built for the one property), each in a fresh "
        f"process, one at a time. {settings}\n\n"
        "Ratios are veribattery / Storm. \"Storm inside\" says whether Storm's value lies "
        "in veribattery's certified interval. stormpy's default environment is Storm's "
        "sound one: its value is certified to 1e-6 relative (Storm's default precision), "
        "ours to 1e-9, so a \"no\" is Storm's value within its own precision but outside "
        "our narrower interval; compare the QComp exact value, Storm's exact engine's as "
        "QComp records it. \"(scaled)\": larger constants than any published instance.\n\n"
        + HEADER + "\n".join(rows) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="", help="instances whose label contains this")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds per process")
    parser.add_argument("--memory-gb", type=float, default=12.0,
                        help="address-space cap per process (ulimit -v)")
    parser.add_argument("--out", type=Path, default=HERE.parent / "docs/_bench/scale.md")
    args = parser.parse_args()
    byte_compile_sources()
    memory_kb = int(args.memory_gb * 1024 * 1024)
    settings = (f"Timeout {args.timeout:.0f} s and `ulimit -v` {args.memory_gb:g} GB per "
                f"process; machine: {os.cpu_count()} cores, run {time.strftime('%Y-%m-%d')}.")
    rows: list[str] = []
    args.out.with_suffix(".jsonl").unlink(missing_ok=True)  # raw measurements of this run
    for instance in INSTANCES:
        if args.only not in instance.label:
            continue
        ours = run_ours(instance, args.timeout, memory_kb)
        storm = run_storm(instance, args.timeout, memory_kb)
        rows.append(row(instance, ours, storm))
        print(rows[-1], flush=True)
        write(args.out, rows, settings)
        with args.out.with_suffix(".jsonl").open("a") as raw:
            raw.write(json.dumps({"instance": instance.label, "ours": vars(ours),
                                  "storm": vars(storm)}) + "\n")


if __name__ == "__main__":
    main()
