"""Structure reuse on a p_wsp_c sweep: a MissionSession against independent checks.

Checks the paper's baseline (configs/paper/case1.yaml) at N values of
``environment.p_wsp_c`` strictly inside (0, 1), once with one :class:`MissionSession`
(the state space is built once and re-used) and once with :func:`check_mission`
per point as ``veribattery check`` runs it (answers only, ``keep="answers"``), in
the same process; prints both totals, the speed-up, how many points re-used the state
space, and the largest relative difference of any value.

    python bench/bench_reuse.py              # 50 points
    python bench/bench_reuse.py --points 5   # a quick look
    python bench/bench_reuse.py --cli        # also as a user runs them (processes)

With ``--cli`` it also times what a user runs: one ``veribattery sweep -j 1`` over the
same values against one ``veribattery check --set`` process per value, wall clock,
back to back (both sides pay their process start-up, imports and first build).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import time
from fractions import Fraction
from pathlib import Path

from veribattery.config import MissionConfig, load_config
from veribattery.lang.nodes import Value
from veribattery.mission import MissionSession, check_mission

#: What is kept of each report: its values and whether it re-used the state space
#: (not the report: 100 DTMCs with their per-state results took 2.5 GB).
Kept = tuple[dict[str, Value], bool]

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "paper" / "case1.yaml"


def values(points: int) -> list[float]:
    """p_wsp_c = k/(points+1), k = 1..points."""
    return [float(Fraction(k, points + 1)) for k in range(1, points + 1)]


def grid(points: int) -> list[MissionConfig]:
    """*points* configs, one per value of :func:`values`."""
    return [load_config(CONFIG, (f"environment.p_wsp_c={v!r}",)) for v in values(points)]


def timed_cli(points: int) -> tuple[float, float]:
    """Wall seconds of one ``sweep -j 1`` over the values, and of one ``check`` per value."""
    command = [str(Path(sys.executable).with_name("veribattery"))]  # the installed command
    listed = ",".join(repr(v) for v in values(points))
    start = time.perf_counter()
    subprocess.run([*command, "sweep", str(CONFIG), "--vary", f"environment.p_wsp_c={listed}",
                    "-j", "1", "--format", "csv"], check=True, capture_output=True)
    swept = time.perf_counter() - start
    start = time.perf_counter()
    for v in values(points):
        subprocess.run([*command, "check", str(CONFIG), "--set", f"environment.p_wsp_c={v!r}",
                        "--format", "json"], check=True, capture_output=True)
    return swept, time.perf_counter() - start


def timed(
    check: object, configs: list[MissionConfig]
) -> tuple[float, float, list[Kept]]:
    """Wall-clock and CPU seconds of *check* over *configs*, and what each report gave.

    CPU time is the fairer figure on a shared machine; on a quiet one they agree.
    """
    wall, cpu = time.perf_counter(), time.process_time()
    kept = []
    for cfg in configs:
        report = check(cfg)  # type: ignore[operator]
        kept.append(({**report.values, "recharge_cap": report.recharge_cap_probability},
                     report.reused))
    return time.perf_counter() - wall, time.process_time() - cpu, kept


def independent(cfg: MissionConfig) -> object:
    """One check of *cfg* as ``veribattery check`` runs it: the answers only."""
    return check_mission(cfg, keep="answers")


def largest_difference(a: list[Kept], b: list[Kept]) -> float:
    """The largest relative difference between corresponding values."""
    worst = 0.0
    for (x, _), (y, _) in zip(a, b, strict=True):
        for name, value in x.items():
            ours, theirs = float(value), float(y[name])
            if ours != theirs:
                worst = max(worst, abs(ours - theirs) / max(abs(ours), abs(theirs)))
    return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=50, help="grid points (default 50)")
    parser.add_argument("--cli", action="store_true",
                        help="also time one sweep process against one check process per point")
    args = parser.parse_args()
    configs = grid(args.points)
    checker = MissionSession.for_sweep(lump=True)  # as a sweep runs a run of points
    reused_s, reused_cpu, reused = timed(checker.check, configs)
    fresh_s, fresh_cpu, fresh = timed(independent, configs)
    count = sum(was for _, was in reused)
    print(f"points: {len(configs)}, re-used the state space: {count}")
    print(f"MissionSession: {reused_s:.2f} s wall, {reused_cpu:.2f} s CPU; "
          f"independent checks: {fresh_s:.2f} s wall, {fresh_cpu:.2f} s CPU; "
          f"speed-up {fresh_s / reused_s:.2f}x wall, {fresh_cpu / reused_cpu:.2f}x CPU")
    difference = largest_difference(reused, fresh)
    print(f"largest relative difference of a value: {difference:.3g}")
    if not math.isfinite(difference) or difference > 1e-12:
        raise SystemExit("re-used values differ from independent checks by more than 1e-12")
    if args.cli:
        swept, checked = timed_cli(args.points)
        print(f"veribattery sweep -j 1: {swept:.2f} s wall; {args.points} x veribattery check: "
              f"{checked:.2f} s wall; speed-up {checked / swept:.2f}x")


if __name__ == "__main__":
    main()
