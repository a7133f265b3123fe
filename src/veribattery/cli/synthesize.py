"""``veribattery synthesize CONFIG``: the best return policy, and BS1 measured against it."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import click

from veribattery.cli.files import (
    CSV_SUFFIXES,
    FIGURE_SUFFIXES,
    PathParam,
    check_output_dir,
    check_output_file,
)
from veribattery.cli.output import (
    build_progress,
    print_warnings,
    print_written,
    set_option,
    user_errors,
)
from veribattery.cli.progress import limited
from veribattery.errors import OptionError

if TYPE_CHECKING:
    from veribattery.config import MissionConfig
    from veribattery.render import FastestQuestion
    from veribattery.synthesis.exports import StrategyExport
    from veribattery.synthesis.session import SynthesisResult


@click.command("synthesize",
               short_help="The best return policy for a mission, and BS1 against it.")
@click.argument("config", type=PathParam(path_type=Path))
@set_option
@click.option("--require", "required", multiple=True, metavar="P|bs1",
              help="Also find the fastest strategy with P(success) >= P, or at least as "
                   "safe as BS1 at the config's safe_t (bs1); repeatable. The config's "
                   "requirements on p_success are always answered.")
@click.option("--format", "output_format", type=click.Choice(["table", "json", "csv"]),
              default="table", show_default=True, help="Output format.")
@click.option("--csv", "csv_path", type=PathParam(path_type=Path), metavar="FILE",
              help="Write the strategy's whole threshold table as CSV.")
@click.option("--pareto", "pareto_path", type=PathParam(path_type=Path), metavar="FILE",
              help="Draw the Pareto front with BS1's points (.png, .svg, .pdf, ...); its "
                   "CSV is written beside it unless --pareto-csv names another file.")
@click.option("--pareto-csv", "pareto_csv", type=PathParam(path_type=Path), metavar="FILE",
              help="Write the Pareto front's points as CSV.")
@click.option("--export-strategy", "strategy_file", type=PathParam(path_type=Path),
              metavar="FILE",
              help="Write the table's strategy (safest, then fastest); FILE.json in Storm's "
                   "scheduler JSON, any other name in PRISM's -exportstrat actions form.")
@click.option("--export-induced", "induced_dir", type=PathParam(path_type=Path),
              metavar="DIR",
              help="Write the DTMC that strategy induces and its P(success), expected "
                   "mission time and recharges: DIR/induced.prism and DIR/induced.props.")
@click.option("--force", is_flag=True, help="Overwrite existing output files.")
@click.option("--exact", is_flag=True,
              help="Not available for synthesis (refused): the fastest strategies are "
                   "certified in floating point, with no exact path.")
@click.option("--max-states", type=click.IntRange(min=1), default=None, metavar="N",
              help="Stop the build (exit 2) once more than N states are found.")
def synthesize_command(
    config: Path, overrides: tuple[str, ...], required: tuple[str, ...], output_format: str,
    csv_path: Path | None, pareto_path: Path | None, pareto_csv: Path | None,
    strategy_file: Path | None, induced_dir: Path | None, force: bool, exact: bool,
    max_states: int | None,
) -> None:
    """Synthesise the best return policy for CONFIG's mission (whatever its strategy.mode):
    Pmax of success beside BS1's values, the fastest strategy per requirement on
    P(success), and the strategy's thresholds. Exit 1 if no strategy meets a requirement.
    """
    from veribattery.config import load_config
    from veribattery.synthesis import unasked_requirements
    from veribattery.synthesis.session import FrontRequest, synthesize

    with user_errors():
        if exact:
            raise OptionError("--exact: not available for synthesize (the fastest strategies "
                              "are certified in floating point, with no exact path); drop "
                              "--exact")
        pareto_csv = _check_outputs(csv_path, pareto_path, pareto_csv, force)
        export = _check_strategy_outputs(strategy_file, induced_dir, force)
        _check_distinct(csv_path, pareto_path, pareto_csv, export)
        cfg = load_config(config, overrides)
        questions = _questions(cfg, required)
        wants_front = pareto_path is not None or pareto_csv is not None
        with build_progress(plain=True) as progress:
            stage = getattr(progress, "stage", None)
            result = synthesize(cfg, questions, progress=limited(progress, max_states),
                                as_safe_as_bs1="bs1" in required,
                                front_request=FrontRequest() if wants_front else None,
                                on_stage=None if stage is None else _stage_line(stage),
                                export=export)
        _write_files(result, csv_path, pareto_path, pareto_csv)
        _write_strategy_files(result, induced_dir)
    print_warnings(unasked_requirements(cfg))
    from veribattery.cli import synthesize_output as shown

    {"table": shown.print_table_output, "json": shown.print_json,
     "csv": shown.print_csv}[output_format](result)
    sys.exit(0 if result.all_requirements_met else 1)


def _stage_line(stage: Callable[[str], None]) -> Callable[[str], None]:
    labels = {"build": "building the mission MDP", "Pmax": "Pmax of success",
              "strategy": "the safest, fastest strategy", "BS1": "BS1 at the config's safe_t",
              "fastest": "the fastest strategy per requirement (weighted sums)",
              "front": "the Pareto front (weighted sums)",
              "BS1 points": "BS1's points for the Pareto figure"}

    def say(name: str) -> None:
        stage(labels.get(name, name))

    return say


def _check_outputs(csv_path: Path | None, pareto_path: Path | None,
                   pareto_csv: Path | None, force: bool) -> Path | None:
    """Every output file checked before any work; the Pareto CSV's path (beside the
    figure unless named)."""
    check_output_file(csv_path, "--csv", force=force, suffixes=CSV_SUFFIXES)
    check_output_file(pareto_path, "--pareto", force=force, suffixes=FIGURE_SUFFIXES)
    if pareto_csv is None and pareto_path is not None:
        pareto_csv = pareto_path.with_suffix(".csv")
        check_output_file(pareto_csv, "--pareto (its CSV)", force=force)
    else:
        check_output_file(pareto_csv, "--pareto-csv", force=force, suffixes=CSV_SUFFIXES)
    paths = [p.resolve() for p in (csv_path, pareto_path, pareto_csv) if p is not None]
    if len(set(paths)) < len(paths):
        raise OptionError("--csv, --pareto and --pareto-csv must name different files")
    return pareto_csv


def _check_strategy_outputs(strategy_file: Path | None, induced_dir: Path | None,
                            force: bool) -> StrategyExport | None:
    """The strategy's files checked before any work, as the export they ask for."""
    if strategy_file is None and induced_dir is None:
        return None
    from veribattery.strategies import INDUCED_MODEL, INDUCED_PROPERTIES
    from veribattery.synthesis.exports import StrategyExport

    check_output_file(strategy_file, "--export-strategy", force=force)
    if induced_dir is not None:
        check_output_dir(induced_dir, "--export-induced", force=force,
                         names=(INDUCED_MODEL, INDUCED_PROPERTIES))
    return StrategyExport(strategy_file, induced_dir)


def _check_distinct(csv_path: Path | None, pareto_path: Path | None,
                    pareto_csv: Path | None, export: StrategyExport | None) -> None:
    """The strategy's files must not be the table's or the front's."""
    if export is None:
        return
    from veribattery.strategies import INDUCED_MODEL, INDUCED_PROPERTIES

    induced = () if export.induced_dir is None else (
        export.induced_dir / INDUCED_MODEL, export.induced_dir / INDUCED_PROPERTIES)
    others = {p.resolve() for p in (csv_path, pareto_path, pareto_csv) if p is not None}
    mine = {p.resolve() for p in (export.strategy_file, *induced) if p is not None}
    if others & mine:
        raise OptionError("--export-strategy and --export-induced must name other files "
                          "than --csv, --pareto and --pareto-csv")


def _questions(cfg: MissionConfig, required: tuple[str, ...]) -> list[FastestQuestion]:
    """The config's requirements on P(success), then each ``--require`` but ``bs1``."""
    from veribattery.synthesis.fastest import required_at_least
    from veribattery.synthesis.session import config_requirements

    return [*config_requirements(cfg),
            *(required_at_least(_probability(text)) for text in required if text != "bs1")]


def _probability(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise OptionError(f"--require {text}: not a probability; give a number in [0, 1], "
                          "or bs1") from None


def _write_files(result: SynthesisResult, csv_path: Path | None, pareto_path: Path | None,
                 pareto_csv: Path | None) -> None:
    from veribattery.synthesis import write_pareto_csv, write_pareto_figure, write_threshold_csv

    if csv_path is not None:
        write_threshold_csv(csv_path, result.table)
        print_written(csv_path)
    if pareto_path is not None:
        write_pareto_figure(pareto_path, result.front, result.bs1_front,
                            p_max=result.p_success_max.value)
        print_written(pareto_path)
    if pareto_csv is not None:
        write_pareto_csv(pareto_csv, result.front, result.bs1_front)
        print_written(pareto_csv)


def _write_strategy_files(result: SynthesisResult, induced_dir: Path | None) -> None:
    """The strategy's files, all or nothing."""
    if not result.strategy_files:
        return
    from veribattery._files import write_texts

    if induced_dir is not None:
        induced_dir.mkdir(parents=True, exist_ok=True)
    write_texts(result.strategy_files)
    print_written(*result.strategy_files)
