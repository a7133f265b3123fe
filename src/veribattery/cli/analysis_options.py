"""Options the mission analyses share: counts checked on parsing, and ``--strategy``.

``explain``, ``simulate``, ``distribution`` and ``report`` read them; ``prism``'s
``--explain``/``--simulate`` reuse the counts.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import click

from veribattery.cli.output import fail

if TYPE_CHECKING:
    from veribattery.config import MissionConfig
    from veribattery.pipeline import ProgressCallback
    from veribattery.synthesis.induced_dtmc import InducedMission

__all__ = ["MOST_PATHS", "MOST_RUNS", "STRATEGIES", "counted", "induced_mission",
           "strategy_option"]

#: The most simulated runs asked for at once (each keeps a few bytes of state; numpy cannot
#: size arrays past 2^63), and the most paths shown (10,000 take a minute and a gigabyte).
MOST_RUNS, MOST_PATHS = 10**12, 1000


def counted(name: str, most: int | None = None, least: int = 1
            ) -> Callable[[click.Context, click.Parameter, int], int]:
    """An option callback: a count below *least* (or above *most*) is bad input,
    reported on one line (exit 2)."""

    def check(ctx: click.Context, param: click.Parameter, value: int) -> int:
        if value is not None and value < least:
            fail(f"{name} must be at least {least}, not {value}")
        if value is not None and most is not None and value > most:
            fail(f"{name} must be at most {most:,}, not {value:,}")
        return value

    return check


#: ``--strategy`` names: BS1 (the config's mission) or the synthesised strategy.
STRATEGIES = ("bs1", "optimal")


def _strategy_value(ctx: click.Context, param: click.Parameter, value: str) -> str:
    """An option callback: neither a name nor a file is bad input, on one line (exit 2)."""
    if value not in STRATEGIES and not Path(value).is_file():
        path = Path(value)
        what = ("a folder" if path.is_dir() else "not a regular file" if path.exists()
                else "no file")
        fail(f"--strategy must be bs1, optimal or a strategy file; {what} {value!r}")
    return value


#: ``--strategy bs1|optimal|FILE`` of ``explain``, ``simulate`` and ``distribution``.
strategy_option = click.option(
    "--strategy", "strategy", default="bs1", show_default=True, callback=_strategy_value,
    metavar="bs1|optimal|FILE",
    help="Analyse the mission under BS1 (the config's strategy), synthesize's strategy "
         "(optimal: safest, then fastest) or a strategy FILE of synthesize "
         "--export-strategy: the DTMC it induces on the mission MDP.")


def induced_mission(cfg: MissionConfig, strategy: str,
                    progress: ProgressCallback | None) -> InducedMission:
    """The mission under the strategy ``--strategy`` names (not ``bs1``)."""
    from veribattery.synthesis.induced_dtmc import file_mission, optimal_mission

    if strategy == "optimal":
        return optimal_mission(cfg, progress=progress)
    return file_mission(cfg, Path(strategy), progress=progress)
