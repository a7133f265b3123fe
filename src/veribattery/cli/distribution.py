"""The ``distribution`` command: the whole CDF of mission time, deadlines and quantiles."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import click

from veribattery._text import count_of
from veribattery.cli.analysis_options import induced_mission, strategy_option
from veribattery.cli.files import CSV_SUFFIXES, FIGURE_SUFFIXES, PathParam, check_output_file
from veribattery.cli.output import (
    build_progress,
    print_dim,
    print_warnings,
    print_written,
    set_option,
    user_errors,
)
from veribattery.cli.tables import print_table
from veribattery.errors import OptionError

if TYPE_CHECKING:
    from veribattery.analyses.distribution import Deadline, Distribution


@click.command("distribution", short_help="Mission-time distribution, quantiles, deadlines.")
@click.argument("config", type=PathParam(path_type=Path))
@set_option
@click.option("--reward", default="mt", show_default=True,
              help="Reward structure to accumulate (integer-valued).")
@click.option("--deadline", "deadlines", multiple=True, metavar="D",
              help="P(success within D): minutes (4800, 4800m), hours (80h) or working days "
                   "(5d); repeatable.")
@click.option("--working-day", default="8h", show_default=True,
              help="Length of a working day 'd' (e.g. 8h, 480, 24h).")
@click.option("--coverage", default=0.999, show_default=True,
              type=click.FloatRange(0, 1, min_open=True),
              help="Compute the CDF until this fraction of P(success) and P(failure).")
@click.option("-o", "--output", "csv_path", type=PathParam(path_type=Path),
              help="Write the CDF as CSV (one row per reward level).")
@click.option("--plot", "plot_path", type=PathParam(path_type=Path),
              help="Plot the CDF with quantiles and deadlines (.png, .pdf, .svg).")
@click.option("--force", is_flag=True, help="Overwrite existing -o / --plot files.")
@click.option("--format", "output_format", type=click.Choice(["table", "json", "csv"]),
              default="table", show_default=True,
              help="Output format (csv: the summary's quantity,value rows).")
@strategy_option
def distribution_command(config: Path, overrides: tuple[str, ...], reward: str,
                         deadlines: tuple[str, ...], working_day: str, coverage: float,
                         csv_path: Path | None, plot_path: Path | None, force: bool,
                         output_format: str, strategy: str) -> None:
    """The distribution of mission time to success and to failure for CONFIG (YAML)."""
    from veribattery.analyses.distribution import parse_deadlines, write_csv
    from veribattery.config import load_config
    from veribattery.mission import mission_dtmc

    with user_errors():
        _, limits = parse_deadlines(working_day, deadlines)
        _require_days_read(working_day, limits)
        check_output_file(csv_path, "-o", force=force, suffixes=CSV_SUFFIXES)
        check_output_file(plot_path, "--plot", force=force, suffixes=FIGURE_SUFFIXES)
        if not 0 < coverage <= 1:  # (nan too) before the model is built
            raise OptionError(f"--coverage must be in (0, 1], got {coverage}")
        cfg = load_config(config, overrides)
        with build_progress(plain=True) as progress:
            dtmc = (mission_dtmc(cfg, progress=progress) if strategy == "bs1"
                    else induced_mission(cfg, strategy, progress).dtmc)
            named = [structure.name for structure in dtmc.rewards if structure.name]
            if reward not in named:
                raise OptionError(f"--reward {reward}: the mission has no reward structure "
                                  f"of that name (it has {', '.join(named)})")
            _require_whole(dtmc, reward)
            if progress is not None:
                progress.starting(f"computing the distribution of {reward!r}")
            levels = None if progress is None else (
                lambda done: progress.solving(done, 0, "reward level"))
            dist = _distribution(dtmc, reward, coverage, limits, levels)
        if csv_path is not None:
            print_written(write_csv(dist, csv_path))
        if plot_path is not None:
            from veribattery.analyses.distribution import plot_distribution

            print_written(plot_distribution(dist, limits, plot_path))
    print_warnings(dtmc.warnings)
    if output_format == "json":
        click.echo(json.dumps(_json(dist, limits)))
    elif output_format == "csv":
        click.echo("quantity,value")
        for name, value in _summary(dist, limits):
            click.echo(f'"{name}",{"" if value is None else repr(value)}')
    else:
        _print_table(dist, limits)


def _require_days_read(working_day: str, limits: tuple[Deadline, ...]) -> None:
    """Refuse a ``--working-day`` typed where no ``--deadline`` counts in working days."""
    source = click.get_current_context().get_parameter_source("working_day")
    if source == click.core.ParameterSource.COMMANDLINE and not any(
            d.text.strip().lower().endswith("d") for d in limits):
        raise OptionError(f"--working-day {working_day} is read by a --deadline in working "
                          "days only (e.g. --deadline 10d): give one, or leave out "
                          "--working-day")


def _require_whole(dtmc: object, reward: str) -> None:
    """Refuse a reward structure that is not whole numbers in every state (the
    distribution counts units of it), naming a state and the config keys behind it."""
    from veribattery.checker.kernels.reward_bounded import NonIntegerReward, integer_levels
    from veribattery.explore.build.successors import format_state
    from veribattery.explore.dtmc import DTMC

    assert isinstance(dtmc, DTMC)
    try:
        integer_levels(dtmc.reward(reward).total)
    except NonIntegerReward as exc:
        state = format_state(dtmc.variable_names, dtmc.states[exc.state])
        hint = ("the mission time counts whole minutes: give whole times_min values, or "
                "choose --reward rc" if reward == "mt" else "choose a whole-valued reward")
        raise OptionError(f"--reward {reward}: the distribution counts whole units of "
                          f"{reward!r}, but it is {exc.value:g} in state ({state}); "
                          f"{hint}") from None


def _distribution(dtmc: object, reward: str, coverage: float, limits: tuple[Deadline, ...],
                  progress: Callable[[int], None] | None) -> Distribution:
    from veribattery.analyses.distribution import reward_distribution
    from veribattery.explore.dtmc import DTMC

    assert isinstance(dtmc, DTMC)
    horizon = max((d.value for d in limits), default=0.0)
    return reward_distribution(dtmc, reward, coverage=coverage, horizon=horizon,
                               progress=progress)


def _summary(dist: Distribution, limits: tuple[Deadline, ...]
             ) -> list[tuple[str, float | None]]:
    """The quantities shown; None where undefined (success unreachable, or a quantile
    beyond the coverage)."""
    from veribattery.analyses.distribution import QUANTILES

    rows: list[tuple[str, float | None]] = [
        ("P(success)", dist.p_success), ("P(failure)", dist.p_failure),
        (f"E[{dist.reward} | success]", _defined(dist.expected_given_success))]
    rows += [(f"{q:.0%} quantile of {dist.reward} to success", dist.quantile_or_none(q))
             for q in QUANTILES]
    rows += [(f"P(success within {_deadline(d)})", dist.p_success_within(d.value))
             for d in limits]
    rows.append(("not yet absorbed (bound on the cut-off)", dist.pending))
    return rows


def _deadline(limit: Deadline) -> str:
    """A deadline as typed, then in the reward's units where those differ (80h = 4800)."""
    value = f"{limit.value:g}"
    return value if limit.text.strip() == value else f"{limit.text} = {value}"


def _print_table(dist: Distribution, limits: tuple[Deadline, ...]) -> None:
    levels = count_of(dist.values.size, "level")
    click.echo(f"Distribution of {dist.reward!r} to success/failure: {levels}, up to "
               f"{dist.values[-1]:g}")
    rows = _summary(dist, limits)
    print_table(("quantity", "value"), [(name, "—" if value is None else f"{value:.10g}")
                                        for name, value in rows])
    if any(value is None for _, value in rows):
        print_dim("—: undefined: success is unreachable, or the quantile lies beyond the "
                  "levels computed (raise --coverage)")


def _defined(value: float) -> float | None:
    return None if math.isnan(value) else value


def _json(dist: Distribution, limits: tuple[Deadline, ...]) -> dict[str, object]:
    from veribattery.analyses.distribution import QUANTILES

    return {
        "reward": dist.reward,
        "p_success": dist.p_success,
        "p_failure": dist.p_failure,
        "expected_given_success": _defined(dist.expected_given_success),
        "quantiles": {str(q): dist.quantile_or_none(q) for q in QUANTILES},
        "deadlines": [{"deadline": d.text, "value": d.value,
                       "p_success_within": dist.p_success_within(d.value)} for d in limits],
        "levels": int(dist.values.size),
        "last_level": float(dist.values[-1]),
        "pending": dist.pending,
    }
