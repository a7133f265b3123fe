"""What every command shares: the consoles, one-line errors, value formatting, progress.

Exit status: 0 success (and every requirement holds), 1 a requirement fails,
2 bad input (any :class:`~veribattery.errors.VeribatteryError`, or a usage error).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar

import click
from rich.console import Console
from rich.markup import escape

from veribattery.errors import VeribatteryError

ProgressCallback = Callable[[int, int], None]

F = TypeVar("F", bound=Callable[..., Any])

out = Console(highlight=False, soft_wrap=True)
err = Console(stderr=True, highlight=False, soft_wrap=True)

out = Console(highlight=False, soft_wrap=True)
err = Console(stderr=True, highlight=False, soft_wrap=True)


def fail(message: str) -> None:
    """Report a user error on one line and exit with status 2.

    Context lines after the first (a syntax error's source line and caret) are
    shown on a terminal only, so logs and pipes get exactly one line.
    """
    first, _, context = message.partition("\n")
    err.print(f"[bold red]error:[/] {escape(first)}", markup=True, highlight=False)
    if context and err.is_terminal:
        err.print(context, markup=False, highlight=False)
    sys.exit(2)


@contextmanager
def user_errors() -> Iterator[None]:
    """Turn library errors into one-line messages and exit status 2 (never a traceback)."""
    try:
        yield
    except VeribatteryError as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"{exc.filename or ''}: {exc.strerror or exc}")


@contextmanager
def build_progress() -> Iterator[ProgressCallback | None]:
    """A live state counter on stderr while the state space is explored (TTY only)."""
    if not err.is_terminal:
        yield None
        return
    with err.status("exploring states…") as status:

        def update(states: int, frontier: int) -> None:
            status.update(f"exploring states… {states:,} found, frontier {frontier:,}")

        yield update


def json_value(value: object) -> object:
    """A result value as strict JSON: infinities become the string ``"Infinity"``."""
    if isinstance(value, float) and math.isnan(value):
        return None  # undefined (e.g. a conditional expectation given an impossible event)
    if isinstance(value, float) and math.isinf(value):
        return "Infinity" if value > 0 else "-Infinity"
    return value


def format_value(value: object) -> str:
    """A result value for a table: booleans as true/false, numbers to 12 significant digits."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "Infinity" if math.isinf(value) else f"{value:.12g}"
    return str(value)


def print_warnings(warnings: Sequence[str]) -> None:
    """Print the model's warnings (deadlocks, nondeterminism) to stderr."""
    for warning in warnings:
        err.print(f"[yellow]warning:[/] {escape(warning)}", markup=True)



def set_option(function: F) -> F:
    """The ``--set KEY=VALUE`` option of the mission commands."""
    return click.option(
        "--set", "overrides", multiple=True, metavar="KEY=VALUE",
        help="Override a config key (VALUE is YAML), e.g. --set farm.base=[1,1].",
    )(function)

