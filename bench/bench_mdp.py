"""veribattery against Storm on MDPs of 10^4 to 10^6 states, side by side in one run.

The QComp MDPs (consensus, csma, wlan, zeroconf, firewire, and resource-gathering's
94 states with a cumulative reward of 10^6 steps; vendored in
``bench/qcomp/``, CC-BY 4.0, origin in its README) and the mission's own MDP
(``veribattery emit configs/paper/case1.yaml --set strategy.mode=synthesize``,
issue #23's model, emitted afresh into a temporary folder). Each instance runs
``veribattery prism MODEL --props FILE --property P --const ... --json`` and a
stormpy script (default engine and environment -- Storm's sound one, precision
1e-6 relative -- float; the model built for that one property, as Storm does) in
fresh processes, one after the other, each under a wall-clock timeout and an
address-space cap, ``--repeat`` times; the minimum wall time of each is reported
(the machine is shared), with the load average before and after. The table has
states, choices and transitions, our value and certified interval, Storm's value
and its interval and whether the two meet, QComp's recorded result (Storm's, exact
where QComp has the exact engine's), wall time and peak RSS of both and their
ratios (veribattery / Storm); it is rewritten after every instance, so a stopped
run keeps what it measured.

    python bench/bench_mdp.py [--only consensus] [--repeat 3] [--timeout 900]
        [--memory-gb 8] [--out docs/_bench/mdp.md]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from bench_scale import Measured, byte_compile_sources, measured, ratio_cell

HERE = Path(__file__).resolve().parent
MODELS = HERE / "qcomp"
ROOT = HERE.parent
MISSION = "mission"  # the model emitted from configs/paper/case1.yaml


@dataclass(frozen=True)
class Instance:
    """One model, one property, one set of constants."""

    model: str
    props: str
    prop: str
    constants: dict[str, int | bool] = field(default_factory=dict)
    #: QComp's recorded result for this instance and property (``results/*.json``: Storm
    #: 1.2.4's default engine, or its exact engine where QComp has that run).
    reference: float | bool | None = None
    #: Storm is asked for the initial states only (its sparse engine computes a
    #: reward-bounded until on an MDP for those alone, and refuses otherwise).
    initial_only: bool = False

    @property
    def label(self) -> str:
        consts = " ".join(f"{k}={str(v).lower() if isinstance(v, bool) else v}"
                          for k, v in self.constants.items())
        name = Path(self.model).stem if self.model != MISSION else "mission (case1, synthesize)"
        return f"{name} {consts}".strip()


CONSENSUS = ("consensus/consensus.4.prism", "consensus/consensus.props")
CSMA_3_2 = ("csma/csma.3-2.prism", "csma/csma.props")
CSMA_2_6 = ("csma/csma.2-6.prism", "csma/csma.props")
WLAN = ("wlan/wlan.3.prism", "wlan/wlan.props")
ZEROCONF = ("zeroconf/zeroconf.prism", "zeroconf/zeroconf.props")
FIREWIRE = ("firewire/firewire.false.prism", "firewire/firewire.false.props")
GATHERING = ("resource-gathering/resource-gathering.pm",
             "resource-gathering/resource-gathering.prctl")
ZEROCONF_2 = {"N": 20, "K": 2, "reset": False}
ZEROCONF_4 = {"N": 20, "K": 4, "reset": False}
FIREWIRE_36 = {"delay": 36, "deadline": 200}
FIREWIRE_36_800 = {"delay": 36, "deadline": 800}
GATHERING_LONG = {"B": 1_000_000, "GOLD_TO_COLLECT": 0, "GEM_TO_COLLECT": 0}
GATHERING_1300 = {"B": 1300, "GOLD_TO_COLLECT": 100, "GEM_TO_COLLECT": 100}

#: Ordered from small to large.
INSTANCES: list[Instance] = [
    # (94 states, a cumulative reward of 10^6 steps)
    Instance(*GATHERING, "expgold", GATHERING_LONG, 112032.8394),
    Instance(*CONSENSUS, "c1", {"K": 2}, True),
    Instance(*CONSENSUS, "c2", {"K": 2}, 0.3173772203),
    Instance(*CONSENSUS, "disagree", {"K": 2}, 0.2944237574),
    Instance(*CONSENSUS, "steps_max", {"K": 2}, 362.983681),
    Instance(*CONSENSUS, "steps_min", {"K": 2}, 192.002901),
    Instance(*CSMA_3_2, "all_before_max", {}, 0.8596150365),
    Instance(*CSMA_3_2, "all_before_min", {}, 0.4349666249),
    Instance(*CSMA_3_2, "time_max", {}, 105.2113141),
    Instance(*CSMA_3_2, "time_min", {}, 93.62412895),
    Instance(*CSMA_2_6, "all_before_max", {}, 0.9999995232),
    Instance(*CSMA_2_6, "time_min", {}, 84.59041297),
    Instance(*ZEROCONF, "correct_max", ZEROCONF_2, 2.0119576888287857e-05),
    Instance(*ZEROCONF, "correct_min", ZEROCONF_2, 2.110327218406747e-06),
    Instance(*WLAN, "num_collisions", {"COL": 0}, 1.20143963),
    Instance(*WLAN, "time_max", {"COL": 0}, 3883.421957),
    Instance(*WLAN, "time_min", {"COL": 0}, 1325.0),
    Instance(*FIREWIRE, "elected", FIREWIRE_36, True),
    Instance(*FIREWIRE, "time_max", FIREWIRE_36, 365.0),
    Instance(*FIREWIRE, "time_min", FIREWIRE_36, 138.25),
    # (a reward bound past the product limit: 201 and 801 layers, one at a time)
    Instance(*FIREWIRE, "deadline", FIREWIRE_36, 0.0, initial_only=True),
    Instance(*FIREWIRE, "deadline", FIREWIRE_36_800, 0.939453125, initial_only=True),
    Instance(*ZEROCONF, "correct_max", ZEROCONF_4, 7.257432765695758e-07),
    Instance(*ZEROCONF, "correct_min", ZEROCONF_4, 7.618296755164084e-08),
    Instance(MISSION, MISSION, "p_success_max"),
    Instance(MISSION, MISSION, "exp_mission_time_max"),
    Instance(MISSION, MISSION, "exp_recharges_max"),
    # issue #23's question: the fastest policy with P(success) >= 0.9 (a multi query)
    Instance(MISSION, MISSION, "fastest_1"),
    # (958,894 states, 3,080,702 choices: 1,300 step-bounded rounds, and a minimal
    # expected time over many tied choices; QComp's values from Storm's exact engine)
    Instance(*GATHERING, "expgold", GATHERING_1300, 145.2875014675094),
    Instance(*GATHERING, "expsteps", GATHERING_1300, 1292.5925925925926),
    Instance(*GATHERING, "prgoldgem", GATHERING_1300, 0.6630608525241785),
]

STORM_SCRIPT = """
import json, sys, stormpy
prog = stormpy.parse_prism_program(sys.argv[1])
props = [p for p in stormpy.parse_properties(open(sys.argv[2]).read(), prog)
         if p.get_name() == sys.argv[3]]
model = stormpy.build_model(prog, props)
result = stormpy.model_checking(model, props[0], only_initial_states=sys.argv[4:] == ["initial"])
intervals = []
if not hasattr(result, "get_truth_values_vector"):
    found = [float(result.get_value(s)) for s in model.initial_states]
    for s in model.initial_states:
        bounded = result[s]  # stormpy's sound default: the value with its interval
        intervals.append([float(bounded.lower), float(bounded.upper)]
                         if bounded.has_lower and bounded.has_upper else None)
else:
    truth = result.get_truth_values_vector()
    found = [bool(truth[s]) for s in model.initial_states]
print(json.dumps({"states": model.nr_states, "choices": model.nr_choices,
                  "transitions": model.nr_transitions, "values": found,
                  "intervals": intervals}))
"""


def with_constants(model: Path, constants: dict[str, int | bool], folder: Path) -> Path:
    """A copy of *model* with its open constants defined (stormpy takes no -const)."""
    text = model.read_text()
    for name, value in constants.items():
        literal = str(value).lower() if isinstance(value, bool) else str(value)
        text = re.sub(rf"const\s+(int|double|bool)\s+{re.escape(name)}\s*;",
                      rf"const \1 {name} = {literal};", text)
    path = folder / model.name
    path.write_text(text)
    return path


def cli_constant(value: int | bool) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def run_ours(instance: Instance, files: tuple[Path, Path], timeout: float,
             memory_kb: int, *options: str) -> Measured:
    """``veribattery prism`` on *instance*, with *options* (``--exact``) added."""
    exe = str(Path(sys.executable).parent / "veribattery")
    consts = [arg for k, v in instance.constants.items()
              for arg in ("--const", f"{k}={cli_constant(v)}")]
    return measured([exe, "prism", str(files[0]), "--props", str(files[1]), "--property",
                     instance.prop, *consts, *options, "--json"], timeout, memory_kb)


def run_storm(instance: Instance, files: tuple[Path, Path], timeout: float,
              memory_kb: int, script: str = STORM_SCRIPT) -> Measured:
    """The stormpy *script* on *instance* (the model with its constants written in)."""
    with tempfile.TemporaryDirectory() as tmp:
        model = with_constants(files[0], instance.constants, Path(tmp))
        initial = ["initial"] if instance.initial_only else []
        return measured([sys.executable, "-c", script, str(model), str(files[1]),
                         instance.prop, *initial], timeout, memory_kb)


def best_of(runs: list[Measured]) -> Measured:
    """The fastest successful run (the last failure if none succeeded)."""
    good = [r for r in runs if r.output is not None]
    return min(good, key=lambda r: r.wall_s) if good else runs[-1]


def emit_mission(folder: Path) -> tuple[Path, Path]:
    """The mission MDP of configs/paper/case1.yaml, emitted into *folder*, with the
    requirement ``p_success >= 0.9`` (its properties then hold ``fastest_1``)."""
    exe = str(Path(sys.executable).parent / "veribattery")
    subprocess.run([exe, "emit", str(ROOT / "configs/paper/case1.yaml"), "--set",
                    "strategy.mode=synthesize", "--set", 'requirements=["p_success >= 0.9"]',
                    "-o", str(folder)], check=True, capture_output=True)
    return folder / "model.prism", folder / "properties.props"


def _number(value: object) -> float | bool | None:
    """A JSON value as a number (``"inf"`` and the like included) or a truth value."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return None
    return float(value) if isinstance(value, (int, float)) else None


def _show(value: float | bool | None) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value).lower()
    return f"{value:.12g}"


def _storm_value(storm: Measured, ours: float | bool | None
                 ) -> tuple[float | bool | None, list[float] | None]:
    """Storm's value at the initial states (the one nearer to ours) and its interval."""
    output = storm.output or {}
    found = [_number(v) for v in output.get("values") or []]  # type: ignore[union-attr]
    intervals = list(output.get("intervals") or [])  # type: ignore[union-attr]
    pairs = [(v, intervals[k] if k < len(intervals) else None)
             for k, v in enumerate(found) if v is not None]
    if not pairs:
        return None, None
    if isinstance(ours, float) and all(isinstance(v, float) for v, _ in pairs):
        pairs.sort(key=lambda pair: abs(float(pair[0]) - ours))  # type: ignore[arg-type]
    return pairs[0]


def _meet(bounds: object, value: float | bool | None, theirs: float | bool | None,
          interval: list[float] | None) -> str:
    """Whether Storm's interval meets our certified one (Storm gives none for multi(...):
    its default method approximates the Pareto front to 1e-4, absolute)."""
    if theirs is None or value is None:
        return ""
    if isinstance(theirs, bool) or isinstance(value, bool):
        return "yes" if theirs == value else "**no**"
    if not interval:
        return "(Storm: no interval)"
    if isinstance(bounds, list):
        low, high = _number(bounds[0]), _number(bounds[1])
        if isinstance(low, float) and isinstance(high, float):
            return "yes" if low <= interval[1] and interval[0] <= high else "**no**"
    return ""


def row(instance: Instance, ours: Measured, storm: Measured) -> str:
    """One markdown table row."""
    result = (ours.output or {}).get("results", [{}])[0] if ours.output else {}
    assert isinstance(result, dict)
    model = (ours.output or {}).get("model", {}) if ours.output else {}
    assert isinstance(model, dict)
    timings = (ours.output or {}).get("timings_s", {}) if ours.output else {}
    assert isinstance(timings, dict)
    bounds = result.get("bounds")
    value = _number(result.get("value"))
    theirs, interval = _storm_value(storm, value)
    if value is None:
        ours_cell = ours.failure or "-"
    elif isinstance(bounds, list):
        ours_cell = f"{_show(value)} [{_show(_number(bounds[0]))}, {_show(_number(bounds[1]))}]"
    else:
        ours_cell = _show(value)
    storm_cell = _show(theirs) if theirs is not None else (storm.failure or "-")
    if interval:
        storm_cell += f" [{_show(interval[0])}, {_show(interval[1])}]"
    time_ratio = ours.wall_s / storm.wall_s if ours.output and storm.output else math.nan
    rss_ratio = ours.peak_mb / storm.peak_mb if ours.output and storm.output else math.nan
    split = (f"{timings.get('build', math.nan):.1f} + {timings.get('check', math.nan):.1f}"
             if timings else "")
    sizes = " | ".join(str(model.get(k, "")) for k in ("states", "choices", "transitions"))
    storm_states = (storm.output or {}).get("states", "") if storm.output else ""
    return (f"| {instance.label} | {instance.prop} | {sizes} | {storm_states} | {ours_cell} "
            f"| {storm_cell} | {_meet(bounds, value, theirs, interval)} "
            f"| {_show(instance.reference)} "
            f"| {ours.wall_s:.1f} | {split} | {storm.wall_s:.1f} | {ratio_cell(time_ratio, ours)} "
            f"| {ours.peak_mb:.0f} | {storm.peak_mb:.0f} | {ratio_cell(rss_ratio, ours)} |")


HEADER = (
    "| instance | property | states | choices | transitions | Storm states "
    "| veribattery value [certified interval] | Storm value [its interval] "
    "| intervals meet | QComp "
    "| ours s | ours build + check s | Storm s | time ratio | ours MB | Storm MB "
    "| RSS ratio |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
)


def write(out: Path, rows: list[str], settings: str) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(
        "# MDPs: veribattery and Storm on QComp MDPs and the mission MDP\n\n"
        "Generated by `bench/bench_mdp.py` (do not edit by hand). Whole-process wall "
        "time and peak RSS of `veribattery prism ... --json` and of a stormpy script "
        "(default engine and environment, float, the model built for the one property), "
        "each in a fresh "
        f"process, one after the other. {settings}\n\n"
        "Ratios are veribattery / Storm; \"ours build + check\" is veribattery's own split "
        "of its time (the rest is start-up and parsing). Both answers are certified: "
        "stormpy's default environment is Storm's sound one, whose value comes with an "
        "interval of relative width at most 1e-6 (Storm's default precision), where "
        "veribattery's is at most 1e-9. \"intervals meet\" says whether the two "
        "intervals overlap, as they must if both are right; for `multi(...)` Storm gives a "
        "value without an interval, from a Pareto approximation of default precision 1e-4 "
        "(absolute), and for firewire's reward-bounded `deadline` (Storm's epochs, "
        "computed for the initial state only, as its sparse engine requires) a value "
        "without one. \"QComp\": the result "
        "QComp records for the instance (Storm 1.2.4; exact where QComp has the exact "
        "engine's run: zeroconf, firewire).\n\n"
        + HEADER + "\n".join(rows) + "\n")


def load_average() -> str:
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def parsed_options(description: str, timeout: float, out: Path) -> argparse.Namespace:
    """The options of an MDP benchmark, parsed (src/ byte-compiled before any timing)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--only", default="", help="instances whose label contains this")
    parser.add_argument("--repeat", type=int, default=1, help="runs per tool; the min counts")
    parser.add_argument("--timeout", type=float, default=timeout, help="seconds per process")
    parser.add_argument("--memory-gb", type=float, default=8.0,
                        help="address-space cap per process (ulimit -v)")
    parser.add_argument("--out", type=Path, default=out)
    args = parser.parse_args()
    byte_compile_sources()
    return args


def settings_text(args: argparse.Namespace, start_load: str) -> str:
    """How a table's runs were made: repeats, limits, machine and load, and when."""
    return (f"Best of {args.repeat} run(s) each; timeout {args.timeout:.0f} s and "
            f"`ulimit -v` {args.memory_gb:g} GB per process; machine: {os.cpu_count()} "
            f"cores shared with other work, load average (1/5/15 min) {start_load} at the "
            f"start and {load_average()} at the last row; run "
            f"{time.strftime('%Y-%m-%d %H:%M %Z')}.")


def measure(instance: Instance, files: tuple[Path, Path], args: argparse.Namespace,
            raw: Path) -> str:
    """*instance* (its model and properties *files*) run ``args.repeat`` times by each
    tool, under its limits: the table row of the best runs (every run appended to
    *raw*, a JSON line)."""
    memory_kb = int(args.memory_gb * 1024 * 1024)
    ours_runs, storm_runs = [], []
    for _ in range(args.repeat):
        ours_runs.append(run_ours(instance, files, args.timeout, memory_kb))
        storm_runs.append(run_storm(instance, files, args.timeout, memory_kb))
    with raw.open("a") as out:
        out.write(json.dumps({"instance": instance.label, "property": instance.prop,
                              "ours": [vars(r) for r in ours_runs],
                              "storm": [vars(r) for r in storm_runs]}) + "\n")
    return row(instance, best_of(ours_runs), best_of(storm_runs))


def main() -> None:
    args = parsed_options(__doc__.splitlines()[0], 900.0, ROOT / "docs/_bench/mdp.md")
    start_load = load_average()
    rows: list[str] = []
    args.out.with_suffix(".jsonl").unlink(missing_ok=True)  # raw measurements of this run
    with tempfile.TemporaryDirectory() as tmp:
        mission: tuple[Path, Path] | None = None
        for instance in INSTANCES:
            if args.only not in f"{instance.label} {instance.prop}":
                continue
            if instance.model == MISSION:
                mission = mission or emit_mission(Path(tmp))
                files = mission
            else:
                files = (MODELS / instance.model, MODELS / instance.props)
            rows.append(measure(instance, files, args, args.out.with_suffix(".jsonl")))
            print(rows[-1], flush=True)
            write(args.out, rows, settings_text(args, start_load))


if __name__ == "__main__":
    main()
