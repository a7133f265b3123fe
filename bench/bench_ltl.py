"""veribattery against Storm on LTL properties of QComp DTMCs and MDPs, side by side.

The vendored QComp models (``bench/qcomp/``, CC-BY 4.0) with LTL properties over their
own labels and variables (written here: QVBS has no LTL properties for them), each run
as ``veribattery prism MODEL --props FILE --property NAME --const ... --json`` and as a
stormpy script (default engine and environment, float; Storm translates the formula
with its own LTL toolchain), in fresh processes, one after the other, ``--repeat``
times; the minimum wall time and the peak RSS of each, their ratios (veribattery /
Storm), both values and whether they agree to 1e-6 (Storm's default precision).

    python bench/bench_ltl.py [--only herman] [--repeat 2] [--out docs/_bench/ltl.md]
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

from bench_mdp import (
    MODELS,
    ROOT,
    Instance,
    best_of,
    load_average,
    parsed_options,
    run_ours,
    run_storm,
    settings_text,
)
from bench_scale import Measured, ratio_cell

#: (model, constants, property name, LTL property).
CASES: list[tuple[str, dict[str, int | bool], str, str]] = [
    ("leader_sync/leader_sync.5-4.prism", {}, "elected_stays",
     'P=? [ F G "elected" ]'),
    ("leader_sync/leader_sync.5-4.prism", {}, "elected_twice",
     'P=? [ F ("elected" & (X "elected")) ]'),
    ("egl/egl.prism", {"N": 5, "L": 8}, "both_know", 'P=? [ (F "knowA") & (F "knowB") ]'),
    ("egl/egl.prism", {"N": 5, "L": 8}, "b_first",
     'P=? [ (!"knowA" U "knowB") & (F "knowA") ]'),
    ("crowds/crowds.prism", {"TotalRuns": 5, "CrowdSize": 10}, "seen_not_twice",
     "P=? [ (F observe0>0) & (G observe0<=1) ]"),
    ("brp/brp.prism", {"N": 64, "MAX": 5}, "success_no_retry",
     "P=? [ (F s=5) & (G !(nrtr>1)) ]"),
    ("consensus/consensus.4.prism", {"K": 2}, "agree_fg",
     'Pmin=? [ (F "finished") & (F G "agree") ]'),
    ("csma/csma.3-2.prism", {}, "no_backoff_all",
     'Pmax=? [ (G !"collision_max_backoff") & (F "all_delivered") ]'),
    ("wlan/wlan.3.prism", {"COL": 0}, "both_sent", "Pmin=? [ (F s1=12) & (F s2=12) ]"),
    ("zeroconf/zeroconf.prism", {"N": 20, "K": 2, "reset": False}, "correct_then_stay",
     "Pmax=? [ F (l=4 & ip=1 & (X l=4)) ]"),
    ("firewire/firewire.false.prism", {"delay": 36, "deadline": 200}, "done_gf",
     'Pmin=? [ G F "done" ]'),
    # (131,072 states, 129 million transitions, every state initial)
    ("herman/herman.17.prism", {}, "fg_stable", 'P=? [ F G "stable" ]'),
]

STORM_SCRIPT = """
import json, sys, stormpy
prog = stormpy.parse_prism_program(sys.argv[1])
props = [p for p in stormpy.parse_properties(open(sys.argv[2]).read(), prog)
         if p.get_name() == sys.argv[3]]
model = stormpy.build_model(prog, props)
result = stormpy.model_checking(model, props[0], only_initial_states=True)
found = [float(result.get_value(s)) for s in model.initial_states]
print(json.dumps({"states": model.nr_states, "transitions": model.nr_transitions,
                  "values": found}))
"""


def _props_file(folder: Path, model: str, name: str, text: str) -> Path:
    """The family's own labels are in the model; the property goes in a file of its own."""
    path = folder / f"{Path(model).stem}.{name}.props"
    path.write_text(f'"{name}": {text};\n')
    return path


def _value(run: Measured, ours: bool) -> float | None:
    data = run.output
    if data is None:
        return None
    value = data["results"][0]["value"] if ours else data["values"][0]  # type: ignore[index]
    return None if value is None else float(value)


def row(case: tuple[str, dict[str, int | bool], str, str], ours: Measured,
        storm: Measured) -> str:
    model, constants, _name, text = case
    mine, theirs = _value(ours, True), _value(storm, False)
    agree = ("yes" if mine is not None and theirs is not None
             and abs(mine - theirs) <= 1e-6 * max(1.0, abs(theirs)) else "no")
    states = ours.output["model"]["states"] if ours.output else "-"  # type: ignore[index]
    consts = " ".join(f"{k}={str(v).lower()}" for k, v in constants.items())
    return (f"| {Path(model).stem} {consts} | `{text}` | {states} | {mine} | {theirs} | "
            f"{agree} | {ours.wall_s:.2f} | {storm.wall_s:.2f} | "
            f"{ratio_cell(_ratio(ours.wall_s, storm), ours)} | {ours.peak_mb:.0f} | "
            f"{storm.peak_mb:.0f} | {ratio_cell(_ratio(ours.peak_mb, storm, rss=True), ours)} |")


def _ratio(mine: float, storm: Measured, *, rss: bool = False) -> float:
    theirs = storm.peak_mb if rss else storm.wall_s
    return mine / theirs if storm.output is not None and theirs > 0 else math.nan


def main() -> None:
    args = parsed_options(__doc__.splitlines()[0], 900.0, ROOT / "docs/_bench/ltl.md")
    memory_kb = int(args.memory_gb * 1024 * 1024)
    start = load_average()
    rows: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        for case in CASES:
            model, constants, name, text = case
            if args.only not in f"{model} {name}":
                continue
            files = (MODELS / model, _props_file(Path(tmp), model, name, text))
            instance = Instance(model, str(files[1]), name, constants)
            ours = best_of([run_ours(instance, files, args.timeout, memory_kb)
                            for _ in range(args.repeat)])
            storm = best_of([run_storm(instance, files, args.timeout, memory_kb,
                                       STORM_SCRIPT) for _ in range(args.repeat)])
            rows.append(row(case, ours, storm))
            print(rows[-1], flush=True)
            _write(args.out, rows, settings_text(args, start))


def _write(out: Path, rows: list[str], settings: str) -> None:
    head = ("| instance | property | states | veribattery | Storm | agree (1e-6) | ours s | "
            "Storm s | time ratio | ours MB | Storm MB | RSS ratio |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|---|")
    out.write_text("# LTL: veribattery and Storm on QComp models\n\nGenerated by "
                   "`bench/bench_ltl.py` (do not edit by hand). Whole-process wall time and "
                   "peak RSS of `veribattery prism ... --json` and of a stormpy script "
                   "(default engine, float), fresh processes, one after the other. "
                   f"{settings}\n\n{head}\n" + "\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
