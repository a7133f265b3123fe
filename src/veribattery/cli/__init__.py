"""The ``veribattery`` command line: parse options, call the library, print, set the exit code.

Each command lives in its own module and imports what it needs late, so that a
command pays only for its own imports. Exit status: 0 success (and every
requirement holds), 1 a requirement fails, 2 bad input (any
:class:`~veribattery.errors.VeribatteryError`, or a usage error).
"""

from __future__ import annotations

from collections.abc import Sequence

import click

from veribattery.cli.distribution import distribution_command
from veribattery.cli.explain import explain_command, simulate_command
from veribattery.cli.mission import check_command, emit_command
from veribattery.cli.phm import phm_group, recheck_command
from veribattery.cli.prism import prism_command
from veribattery.cli.reproduce import reproduce_command
from veribattery.cli.sweep import sweep_command

__all__ = ["cli", "main"]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="veribattery")
def cli() -> None:
    """Verify battery-powered robot missions with probabilistic model checking."""


for _command in (check_command, emit_command, prism_command, reproduce_command, sweep_command):
    cli.add_command(_command)
cli.add_command(explain_command)
cli.add_command(simulate_command)
cli.add_command(phm_group)
cli.add_command(recheck_command)
cli.add_command(distribution_command)


def main(argv: Sequence[str] | None = None) -> None:
    """Console-script entry point."""
    from veribattery._memory import map_large_blocks

    map_large_blocks()  # freed arrays leave the process at once (see _memory)
    cli.main(args=list(argv) if argv is not None else None, prog_name="veribattery")
