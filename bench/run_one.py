"""Run one tool on one model in this process and print a JSON line of sizes, times, memory.

Called by bench_models.py in a fresh subprocess per measurement, so peak RSS is the tool's own.
"""

from __future__ import annotations

import json
import resource
import sys
import time
from pathlib import Path


def run_veribattery(model: Path, props: Path) -> dict[str, object]:
    from veribattery.pipeline import check_prism_file

    start = time.perf_counter()
    run = check_prism_file(model, props_source=props, keep="answers")  # as the CLI
    total = time.perf_counter() - start
    return {
        "states": run.dtmc.num_states,
        "transitions": run.dtmc.num_transitions,
        "build_s": run.timings_s["parse"] + run.timings_s["build"],
        "check_s": run.timings_s["check"],
        "total_s": total,
        "values": [r.value for r in run.results],
    }


def run_storm(model: Path, props: Path) -> dict[str, object]:
    import stormpy

    start = time.perf_counter()
    program = stormpy.parse_prism_program(str(model))
    properties = stormpy.parse_properties(props.read_text(), program)
    built = stormpy.build_model(program, properties)
    mid = time.perf_counter()
    init = built.initial_states[0]
    values = [stormpy.model_checking(built, p).get_value(init) for p in properties]
    end = time.perf_counter()
    return {
        "states": built.nr_states,
        "transitions": built.nr_transitions,
        "build_s": mid - start,
        "check_s": end - mid,
        "total_s": end - start,
        "values": values,
    }


def main() -> None:
    tool, model, props = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
    result = (run_veribattery if tool == "veribattery" else run_storm)(model, props)
    result["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps(result))


if __name__ == "__main__":
    main()
