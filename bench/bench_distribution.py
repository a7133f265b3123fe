"""Benchmark: the whole mission-time CDF of case1 against one ``check`` and one Storm query.

Target (issue 7): the CDF up to its 99.9 % quantile in at most 10x the time of one
``check`` of the same config. Storm's reward-bounded reachability answers a single
deadline T; its time for one T is reported beside ours.

    .venv/bin/python bench/bench_distribution.py [CONFIG] [--storm]
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("config", nargs="?", default=str(REPO / "configs/paper/case1.yaml"))
    parser.add_argument("--storm", action="store_true", help="also time Storm for one T")
    args = parser.parse_args()

    from veribattery.analyses.distribution import reward_distribution
    from veribattery.config import load_config
    from veribattery.mission import check_mission, mission_dtmc, mission_files

    cfg = load_config(args.config, ())
    start = time.perf_counter()
    report = check_mission(cfg)
    check_s = time.perf_counter() - start
    print(f"check: {check_s:.1f} s ({report.run.dtmc.num_states:,} states)")

    start = time.perf_counter()
    dtmc = mission_dtmc(cfg)
    build_s = time.perf_counter() - start
    start = time.perf_counter()
    dist = reward_distribution(dtmc, coverage=0.999)
    dist_s = time.perf_counter() - start
    q999 = dist.quantile(0.999)
    print(f"distribution: build {build_s:.1f} s + pass {dist_s:.1f} s over "
          f"{dist.values.size:,} levels (99.9 % quantile {q999:g}, cut-off {dist.pending:.2e})")
    print(f"ratio (build + pass) / check: {(build_s + dist_s) / check_s:.2f} (target <= 10)")
    print(f"peak RSS: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")
    if args.storm:
        _storm(mission_files(cfg).model, q999, dist.p_success_within(q999))


def _storm(model_text: str, bound: float, ours: float) -> None:
    import stormpy

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.prism"
        path.write_text(model_text)
        start = time.perf_counter()
        program = stormpy.parse_prism_program(str(path))
        props = stormpy.parse_properties(f'P=? [ F{{"mt"}}<={bound:g} "success" ]', program)
        model = stormpy.build_model(program, props)
        built = time.perf_counter() - start
        result = stormpy.model_checking(model, props[0], only_initial_states=True)
        value = result.get_value_vector()[model.initial_states[0]]
        total = time.perf_counter() - start
    print(f"Storm, one T={bound:g}: {total:.1f} s (build {built:.1f} s); value {value:.10g}, "
          f"ours {ours:.10g}")


if __name__ == "__main__":
    main()
