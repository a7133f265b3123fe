"""Benchmark: 10,000 simulated runs of a mission against one ``check`` of the same config.

The issue's budget: the simulation (sampling every run and estimating every named
result, on the already-built DTMC) takes at most 10x one ``check`` (parse, build
and check). Exits 1 when the budget is exceeded or an exact value falls outside
its 99.9 % interval.

    python bench/bench_simulate.py                        # case1, 10,000 runs
    python bench/bench_simulate.py configs/paper/case2.yaml --runs 10000 --set strategy.safe_t=0.25
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

from veribattery.analyses.simulate import simulate
from veribattery.config import load_config
from veribattery.mission import check_mission

REPO = Path(__file__).resolve().parent.parent
BUDGET = 10.0


def main() -> int:
    """Time one check and one simulation; print the figures and the ratio."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("config", nargs="?", default=str(REPO / "configs/paper/case1.yaml"))
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()
    cfg = load_config(Path(args.config), tuple(args.overrides))
    start = time.perf_counter()
    report = check_mission(cfg)
    check_s = time.perf_counter() - start
    exact = {r.property.name or r.property.text: float(r.value) for r in report.run.results}
    start = time.perf_counter()
    sim = simulate(report.run.dtmc, [r.property for r in report.run.results],
                   runs=args.runs, seed=args.seed, exact=exact)
    sim_s = time.perf_counter() - start
    print(f"model: {report.run.dtmc.num_states:,} states; check {check_s:.2f} s "
          f"(build {report.run.timings_s['build']:.2f} s)")
    print(f"simulate: {args.runs:,} runs, longest {sim.steps:,} steps, {sim_s:.2f} s "
          f"= {sim_s / check_s:.2f}x check (budget {BUDGET:g}x)")
    for e in sim.estimates:
        print(f"  {e.name}: exact {e.exact:.10g}, estimate {e.estimate:.6g}, "
              f"95% CI [{e.ci95[0]:.6g}, {e.ci95[1]:.6g}]")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS {peak:.0f} MB")
    for warning in sim.warnings():
        print(f"warning: {warning}")
    return 0 if sim_s <= BUDGET * check_s and not any(e.disagrees for e in sim.estimates) else 1


if __name__ == "__main__":
    sys.exit(main())
