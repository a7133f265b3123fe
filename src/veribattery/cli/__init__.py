"""The ``veribattery`` command line: parse options, call the library, print, set the exit code.

Each command lives in its own module, imported only when that command runs (or when
``--help`` lists them all), and imports what it needs late, so that a command pays
only for its own imports. Exit status: 0 success (and every requirement holds), 1 a
requirement fails, 2 bad input (any :class:`~veribattery.errors.VeribatteryError`,
or a usage error), 130 interrupted (Ctrl-C).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Sequence
from typing import Any

import click

__all__ = ["cli", "main"]

#: Command name -> (module, attribute): imported on first use by :class:`_LazyGroup`.
_COMMANDS = {
    "check": ("veribattery.cli.mission", "check_command"),
    "emit": ("veribattery.cli.mission", "emit_command"),
    "prism": ("veribattery.cli.prism", "prism_command"),
    "reproduce": ("veribattery.cli.reproduce", "reproduce_command"),
    "sweep": ("veribattery.cli.sweep", "sweep_command"),
    "explain": ("veribattery.cli.explain", "explain_command"),
    "simulate": ("veribattery.cli.simulate", "simulate_command"),
    "phm": ("veribattery.cli.phm", "phm_group"),
    "recheck": ("veribattery.cli.phm", "recheck_command"),
    "distribution": ("veribattery.cli.distribution", "distribution_command"),
    "report": ("veribattery.cli.report", "report_command"),
    "synthesize": ("veribattery.cli.synthesize", "synthesize_command"),
}


class _LazyGroup(click.Group):
    """A group whose commands in :data:`_COMMANDS` are imported when first asked for
    (commands added with :meth:`add_command` work as usual)."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*super().list_commands(ctx), *_COMMANDS})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        command = super().get_command(ctx, cmd_name)
        if command is None and cmd_name in _COMMANDS:
            module, attribute = _COMMANDS[cmd_name]
            command = getattr(importlib.import_module(module), attribute)
            self.add_command(command, cmd_name)
        return command

    def main(
        self, args: Sequence[str] | None = None, prog_name: str | None = None,
        complete_var: str | None = None, standalone_mode: bool = True, **extra: Any,
    ) -> Any:
        """Click's main, with every usage error on one line (``error: ...``, exit 2)
        like the library's errors, instead of click's usage block."""
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, **extra)
        try:
            result = super().main(args, prog_name, complete_var, False, **extra)
        except click.exceptions.NoArgsIsHelpError as exc:  # `veribattery`, `veribattery phm`
            click.echo(exc.ctx.get_help())  # the help asked for by giving no command
            sys.exit(0)
        except click.UsageError as exc:
            hint = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
            from veribattery.cli.output import shortened

            # (one line: click lists a Choice's values on lines of their own; and its
            # range types call a value that is no number "not a valid integer range")
            text = " ".join(exc.format_message().split()).rstrip(".")
            text = text.replace(" is not a valid integer range", " is not a valid integer")
            text = text.replace(" is not a valid float range", " is not a valid number")
            message = shortened(f"{text}{hint}")
            click.echo(f"error: {message}", err=True)
            sys.exit(2)
        except click.exceptions.Abort:  # Ctrl-C before the command ran
            from veribattery.cli.output import exit_interrupted

            exit_interrupted()
        except click.ClickException as exc:
            exc.show()
            sys.exit(exc.exit_code)
        sys.exit(result if isinstance(result, int) else 0)

    def invoke(self, ctx: click.Context) -> object:
        """Run the command; Ctrl-C ends it with status 130 (not click's 1, which is a
        failed requirement here) and one line, never a traceback; so does running out
        of memory, with status 2 (as a model the build's guard refuses)."""
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt:
            from veribattery.cli.output import exit_interrupted

            exit_interrupted("\ninterrupted")
        except MemoryError as exc:  # past the build's guard: a solve's arrays, say
            detail = str(exc).rstrip(".")
            click.echo(f"error: out of memory{': ' + detail if detail else ''}: the model or "
                       "its analysis needs more memory than this machine has available",
                       err=True)
            sys.exit(2)


@click.group(cls=_LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="veribattery")
def cli() -> None:
    """Verify battery-powered robot missions with probabilistic model checking.

    \b
    Every command follows the same rules:
      --format table|json|csv   results on stdout (csv where they are rows;
                                prism --json = --format json)
      -o FILE|DIR               files written; never over an existing file
                                without --force; all or nothing, no partial file
      exit status               0 ok, 1 a requirement fails, 2 bad input,
                                130 interrupted (Ctrl-C)
    Errors are one line on stderr, naming the file, key or option at fault.
    """


def main(argv: Sequence[str] | None = None) -> None:
    """Console-script entry point."""
    from veribattery._startup import start_process

    start_process()
    cli.main(args=list(argv) if argv is not None else None, prog_name="veribattery")
