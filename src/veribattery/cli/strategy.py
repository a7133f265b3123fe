"""``prism --export-strategy FILE``, ``--export-induced DIR``, ``--strategy-property``:
an MDP property's optimal strategy and the DTMC it induces, written to files."""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from veribattery.cli.files import PathParam, check_output_dir, check_output_file
from veribattery.cli.output import print_written, user_errors
from veribattery.errors import OptionError

if TYPE_CHECKING:
    from veribattery.lang import Property
    from veribattery.pipeline import ModelCheckRun
    from veribattery.pipeline.mdp import MdpCheckRun

__all__ = ["check_strategy_options", "export_run_strategy", "hopeless_export_check",
           "strategy_options"]


def strategy_options(function: Callable[..., None]) -> Callable[..., None]:
    """The ``--export-strategy``, ``--export-induced`` and ``--strategy-property`` options."""
    for option in reversed((
        click.option("--export-strategy", "strategy_file", type=PathParam(path_type=Path),
                     metavar="FILE",
                     help="MDP: write an optimal strategy; FILE.json in Storm's scheduler "
                     "JSON, any other name in PRISM's -exportstrat actions form."),
        click.option("--export-induced", "induced_dir", type=PathParam(path_type=Path),
                     metavar="DIR",
                     help="MDP: write the DTMC the strategy induces and its property, "
                     "DIR/induced.prism and DIR/induced.props."),
        click.option("--strategy-property", "strategy_property", metavar="INDEX|NAME",
                     help="Whose strategy: a 1-based index among the checked properties "
                     "or a name [default: the first that has one]."),
    )):
        function = option(function)
    return function


def check_strategy_options(options: Mapping[str, Any]) -> None:
    """Refuse the strategy options' files before any work starts (exists without
    ``--force``, missing folder), and combinations that would ignore them."""
    strategy_file, induced_dir = options["strategy_file"], options["induced_dir"]
    wanted = strategy_file is not None or induced_dir is not None
    if options["strategy_property"] is not None and not wanted:
        raise OptionError("--strategy-property: give --export-strategy FILE or "
                          "--export-induced DIR too")
    if not wanted:
        return
    for other in ("explain", "simulate"):
        if options[other] is not None:
            raise OptionError(f"--{other} does not check the properties: it cannot be "
                              "combined with --export-strategy or --export-induced")
    check_output_file(strategy_file, "--export-strategy", force=options["force"])
    if induced_dir is not None:
        from veribattery.strategies import INDUCED_MODEL, INDUCED_PROPERTIES

        check_output_dir(induced_dir, "--export-induced", force=options["force"],
                         names=(INDUCED_MODEL, INDUCED_PROPERTIES))
        induced = {induced_dir.resolve(), *((induced_dir / name).resolve()
                                            for name in (INDUCED_MODEL, INDUCED_PROPERTIES))}
        if strategy_file is not None and strategy_file.resolve() in induced:
            raise OptionError(f"--export-strategy {strategy_file} is --export-induced's "
                              "folder or one of its files: name the strategy file elsewhere")


def hopeless_export_check(options: Mapping[str, Any]
                          ) -> Callable[[str, Sequence[Property]], None] | None:
    """What refuses, once the properties are parsed and before the model is built, a
    strategy export that cannot succeed (a DTMC; a property with no strategy, see
    :func:`~veribattery.strategies.refuse_hopeless_export`); None without an export."""
    if options["strategy_file"] is None and options["induced_dir"] is None:
        return None
    from veribattery.strategies import refuse_hopeless_export

    return functools.partial(refuse_hopeless_export, selector=options["strategy_property"])


def export_run_strategy(run: ModelCheckRun | MdpCheckRun, options: Mapping[str, Any]) -> None:
    """Write the files the strategy options ask for (nothing if none), or exit 2
    naming the property that has no strategy."""
    strategy_file, induced_dir = options["strategy_file"], options["induced_dir"]
    if strategy_file is None and induced_dir is None:
        return
    from veribattery.pipeline.mdp import MdpCheckRun as MdpRun
    from veribattery.strategies import export_strategy

    with user_errors():
        if not isinstance(run, MdpRun):
            from veribattery.strategies import DTMC_HAS_NO_STRATEGY

            raise OptionError(DTMC_HAS_NO_STRATEGY)
        written = export_strategy(run, selector=options["strategy_property"],
                                  strategy_file=strategy_file, induced_dir=induced_dir)
    print_written(*written)
