"""What every command shares: the consoles, one-line errors, value formatting, progress.

Exit status: 0 success (and every requirement holds), 1 a requirement fails,
2 bad input (any :class:`~veribattery.errors.VeribatteryError`, or a usage error).
"""

from __future__ import annotations

import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, NoReturn, TypeVar, cast

import click
from click.core import ParameterSource

from veribattery.cli.progress import PlainProgress, intervals, rate_text, solve_text
from veribattery.cli.spinner import DeferredStatus
from veribattery.errors import OptionError, VeribatteryError

if TYPE_CHECKING:
    from rich.console import Console

    from veribattery.checker import CheckResult

F = TypeVar("F", bound=Callable[..., Any])


class _LazyConsole:
    """A rich ``Console`` made on first use: ``--help`` and commands that print no rich
    output never import rich (its import is a noticeable part of start-up)."""

    def __init__(self, **options: Any):
        self._options = options
        self._console: Console | None = None

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):  # copy/pickle probes: not the console's business
            raise AttributeError(name)
        return getattr(self.console, name)

    @property
    def console(self) -> Console:
        """The rich console itself (made now if not yet made)."""
        console = self.__dict__.get("_console")
        if console is None:
            from rich.console import Console

            console = self._console = Console(**self.__dict__.get("_options", {}))
            # On a terminal, long lines wrap at word boundaries to its width; in pipes
            # and logs a message stays on one line, whatever its length.
            console.soft_wrap = not console.is_terminal
        return console


def rich_console(console: Console) -> Console:
    """The real console behind :data:`out` or :data:`err`, for rich objects that use
    it as a context manager or check its type (``Progress``, ``Live``)."""
    return console.console if isinstance(console, _LazyConsole) else console


# emoji=False: user text such as ``--vary k=a:b:c`` or ``my:warning:x.yaml`` is printed
# as typed, never with ``:b:`` or ``:warning:`` turned into emoji.
out: Console = cast("Console", _LazyConsole(highlight=False, emoji=False))
err: Console = cast("Console", _LazyConsole(stderr=True, highlight=False, emoji=False))


def escape(text: str) -> str:
    """Escape rich markup in *text* (rich imported on first use, as for the consoles)."""
    from rich.markup import escape as rich_escape

    return rich_escape(text)


#: An error line longer than this is cut in its middle (a value of 100,000 characters
#: repeated in full made a line nobody reads); where and what stay at its ends.
LONGEST_ERROR = 1_000


def shortened(line: str) -> str:
    """*line*, its middle cut where it is longer than :data:`LONGEST_ERROR`."""
    if len(line) <= LONGEST_ERROR:
        return line
    head, tail = LONGEST_ERROR * 3 // 5, LONGEST_ERROR // 5
    return f"{line[:head]} … ({len(line) - head - tail:,} characters) … {line[-tail:]}"


def fail(*messages: str) -> None:
    """Report user errors, one line each, and exit with status 2.

    Context lines after a message's first (a syntax error's source line and caret)
    are shown on a terminal only, so logs and pipes get exactly one line per error.
    """
    for message in messages:
        first, _, context = message.partition("\n")
        err.print(f"[bold red]error:[/] {escape(shortened(first))}", markup=True,
                  highlight=False)
        if context and err.is_terminal:
            err.print(context, markup=False, highlight=False)
    sys.exit(2)


def exit_interrupted(message: str = "interrupted") -> NoReturn:
    """After Ctrl-C: print *message* on stderr and exit with status 130.

    Ctrl-C is ignored from here on: the process is on its way out, and a second Ctrl-C
    in what remains (the interpreter joining a worker pool's threads at exit) would
    print a traceback, or kill the process by the signal instead of exiting with 130.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    click.echo(message, err=True)
    sys.exit(130)


@contextmanager
def user_errors() -> Iterator[None]:
    """Turn library errors into one-line messages and exit status 2 (never a traceback)."""
    try:
        yield
    except VeribatteryError as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"{exc.filename}: {exc.strerror}" if exc.filename and exc.strerror else str(exc))


def _may_be_terminal(stream: object) -> bool:
    """False when rich would certainly not take *stream* (``sys.stderr``, ``sys.stdout``)
    for a terminal: then rich need not be imported (``--json``, pipes and CI runs do
    not need it)."""
    if {"FORCE_TERMINAL", "TTY_COMPATIBLE", "FORCE_COLOR"} & os.environ.keys():
        return True
    isatty = getattr(stream, "isatty", None)
    return isatty is not None and bool(isatty())


def print_dim(text: str) -> None:
    """Print plain *text* (a note, the timings) on stdout, dim on a terminal.

    Off a terminal rich prints such text unchanged, so it is echoed as is there,
    without importing rich (some 7 % of a small check's start-up).
    """
    if _may_be_terminal(sys.stdout):
        out.print(text, style="dim", markup=False)
    else:
        click.echo(text)


#: Seconds between two updates of the spinner's text by a solve (it is redrawn 12.5
#: times a second; a solve may report thousands of segments a second).
SPINNER_EVERY_S = 0.1


class LiveStatus:
    """The spinner line of :func:`build_progress`: a state counter while the state space
    is explored, then the stage a longer command is in, and how far a solve is."""

    def __init__(self, status: Any) -> None:
        self._status = status
        self._start = self._since = time.monotonic()
        self._next = self._start
        self._subject = ""

    def __call__(self, states: int, frontier: int) -> None:
        rate = rate_text(states, time.monotonic() - self._start)
        self._status.update(f"exploring states… {states:,} found, frontier {frontier:,}, {rate}")

    def stage(self, text: str) -> None:
        """Say (above the spinner) that a new stage starts, and show it on the spinner."""
        err.print(text, markup=False, style="dim")
        self._status.update(f"{text}…")
        self._subject, self._since = "", time.monotonic()

    def starting(self, text: str) -> None:
        """Show on the spinner that a stage of a check begins (nothing printed above it)."""
        self._show(f"{text}…", "")

    def step(self, text: str) -> None:
        """A step of a run of many begins (a forecast's age): a stage, which the spinner
        shows at once (:meth:`PlainProgress.step` also writes it once a line is due)."""
        self.starting(text)

    def checking(self, number: int, count: int, text: str) -> None:
        """Show on the spinner which property is checked."""
        self._show(f"checking property {number} of {count}: {text}…", text)

    def solving(self, done: int, total: int, unit: str) -> None:
        """Show how far the solve is (at most every :data:`SPINNER_EVERY_S`)."""
        now = time.monotonic()
        if now >= self._next:
            self._next = now + SPINNER_EVERY_S
            self._status.update(_one_line(solve_text(self._subject, done, total, unit,
                                                     now - self._since, _room())))

    def _show(self, text: str, subject: str) -> None:
        self._subject, self._since = subject, time.monotonic()
        self._next = self._since
        self._status.update(_one_line(text))


def _one_line(text: str) -> Any:
    """*text* as the spinner shows it: literally (a formula's ``[`` is no markup), cut
    with an ellipsis at the terminal's edge rather than wrapped (the spinner and a
    space take two columns)."""
    from rich.text import Text

    room = _room()
    return Text(text if len(text) <= room else text[:room - 1] + "…")


def _room() -> int:
    """The columns of the spinner's text (the spinner and a space take two)."""
    return max(err.width - 2, 10)


@contextmanager
def build_progress(plain: bool = False) -> Iterator[LiveStatus | PlainProgress | None]:
    """A live spinner on stderr while the state space is explored and the properties
    checked (TTY), or with *plain*, periodic lines when stderr is not a terminal
    (:class:`PlainProgress`, its intervals from ``VERIBATTERY_PROGRESS_S`` if set; a
    bad value is refused on a terminal too, where the spinner does not use it)."""
    first, every = intervals()
    if not _may_be_terminal(sys.stderr) or not err.is_terminal:
        if not plain:
            yield None
            return
        yield PlainProgress(_stderr_line, first=first, every=every)
        return
    status = DeferredStatus(err.status, "exploring states…")
    try:
        yield LiveStatus(status)
    finally:
        status.stop()


def _stderr_line(text: str) -> None:
    click.echo(text, err=True)


def json_value(value: object) -> object:
    """A result value as strict JSON: infinities become the string ``"Infinity"``."""
    if isinstance(value, float) and math.isnan(value):
        return None  # undefined (e.g. a conditional expectation given an impossible event)
    if isinstance(value, float) and math.isinf(value):
        return "Infinity" if value > 0 else "-Infinity"
    return value


def property_value(value: object) -> object:
    """A property's value for ``prism --json``: :func:`json_value`, except that an
    undefined value (``0/0``, ``inf/inf``) is the string ``"NaN"``, as PRISM prints it
    (``null`` would read as "no result")."""
    if isinstance(value, float) and math.isnan(value):
        return "NaN"
    return json_value(value)


def format_value(value: object) -> str:
    """A result value for a table: booleans as true/false, numbers to 12 significant digits."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "Infinity" if math.isinf(value) else f"{value:.12g}"
    return str(value)


def exact_text(result: object) -> str | None:
    """An ``--exact`` result's value as ``p/q`` (``Infinity`` if infinite); None otherwise.

    Duck-typed on :class:`~veribattery.checker.exact.pctl.ExactCheckResult`, so that
    the CLI does not import the exact checker (and python-flint) unless asked to.
    """
    if getattr(result, "exact_values", None) is None:
        return None  # a boolean result, or not an exact run
    exact = getattr(result, "exact", None)
    if exact is None:
        return "Infinity"
    numerator, denominator = _digits(exact.numerator), _digits(exact.denominator)
    return numerator if denominator == "1" else f"{numerator}/{denominator}"


def _digits(n: int) -> str:
    """*n* in decimal, however long (Python refuses ``str`` past 4,300 digits: a
    thousand exact steps of a chain with thirds give 4,771)."""
    try:
        return str(n)
    except ValueError:
        from gmpy2 import mpz  # (not limited; only for such numbers)

        return str(mpz(n))


def format_result(result: CheckResult) -> str:
    """A result for a table: ``p/q ≈ value`` for an exact result, else ``value ± error``.

    An exact ``p/q`` longer than :data:`EXACT_TABLE_CHARS` (hundreds of digits
    on a long mission) is summarised by its digit counts; JSON and CSV output
    carry every digit.
    """
    exact = exact_text(result)
    if exact is not None and exact != "Infinity":
        return format_exact(exact, _approximate(exact, result.value))
    return _certified_text(result)


def _approximate(exact: str, value: object) -> str:
    """The value of an exact ``p/q`` for a table: its double's text, or, where that is
    infinite (``p/q`` beyond the largest double), ``p/q`` itself to as many digits."""
    if not (isinstance(value, float) and math.isinf(value)):
        return format_value(value)
    from decimal import Decimal  # only for such a value

    numerator, _, denominator = exact.partition("/")
    quotient = (Decimal(numerator) / Decimal(denominator or 1)).normalize()
    return f"{quotient:.{TABLE_DIGITS}g}"


#: Longest exact ``p/q`` printed in full in a table.
EXACT_TABLE_CHARS = 40


def format_exact(exact: str, approximate: str) -> str:
    """``p/q ≈ value`` when short (an integer alone: ``8``), else
    ``≈ value (p/q: N/M digits)``.

    Tables that show the long form explain it below them (:data:`EXACT_NOTE`).
    """
    if exact == approximate:
        return exact
    if len(exact) <= EXACT_TABLE_CHARS:
        return f"{exact} ≈ {approximate}"
    numerator, _, denominator = exact.lstrip("-").partition("/")
    digits = f"{len(numerator)}/{len(denominator)}" if denominator else f"{len(numerator)}"
    return f"≈ {approximate} (p/q: {digits} digits)"


#: The footnote of a table with a long exact value.
EXACT_NOTE = ("p/q: N/M digits: the exact rational value has an N-digit numerator and an "
              "M-digit denominator; --format json or csv prints every digit.")


def exact_notes(cells: Iterable[str]) -> list[str]:
    """``[EXACT_NOTE]`` if a table cell is :func:`format_exact`'s long form, else ``[]``."""
    long_form = any(cell.startswith("≈ ") and cell.endswith(" digits)") for cell in cells)
    return [EXACT_NOTE] if long_form else []


#: Significant digits of numbers in tables.
TABLE_DIGITS = 12


def _certified_text(result: CheckResult) -> str:
    """A float result for a table: its value, with ``± error`` when the certified error shows.

    The error is shown when it reaches half a unit in the last printed digit
    (TABLE_DIGITS significant digits), so every digit printed without one is certified.
    """
    text = format_value(result.value)
    error = result.error
    if isinstance(result.value, float) and math.isinf(result.value):
        return _beyond_doubles(result) or text
    if isinstance(result.value, bool) or not math.isfinite(result.value) or error <= 0:
        return text
    if math.isinf(error) or error >= _half_last_digit(result.value):
        return f"{text} ± {error:.2g}"
    return text


def _beyond_doubles(result: CheckResult) -> str | None:
    """``>= largest double`` for a finite value beyond the doubles (an infinite point
    value whose certified interval starts at a finite bound), else None."""
    positive = result.value > 0
    bound = result.lower if positive else result.upper
    if bound is None or not math.isfinite(bound):
        return None
    return f"{'≥' if positive else '≤'} {format_value(bound)}"


def _half_last_digit(value: float) -> float:
    """Half a unit in the last of TABLE_DIGITS significant digits of *value* (0 for 0)."""
    if value == 0:
        return 0.0
    return 0.5 * 10.0 ** (math.floor(math.log10(abs(value))) - TABLE_DIGITS + 1)


def result_bounds(result: CheckResult) -> list[object] | None:
    """``[lower, upper]`` of a numeric result for JSON (None for booleans)."""
    if result.lower is None or result.upper is None:
        return None
    return [json_value(result.lower), json_value(result.upper)]


def print_imprecise(results: Sequence[CheckResult]) -> None:
    """Warn on stderr about every result whose certified interval missed the precision,
    and every result computed without a certificate."""
    for result in results:
        name = result.property.name or result.property.text
        if not result.certified:
            estimate = "" if result.lower is None else (
                f", error estimated at [{result.lower!r}, {result.upper!r}]")
            err.print(f"[yellow]warning:[/] {escape(name)}: not certified (a linear programme "
                      f"solved in floating point{escape(estimate)})", markup=True)
        elif not result.precise and exact_text(result) in (None, "Infinity"):
            interval = escape(f"[{result.lower!r}, {result.upper!r}]")
            err.print(f"[yellow]warning:[/] {escape(name)}: imprecise result, certified "
                      f"interval {interval} is wider than 1e-9 relative / 1e-12 absolute",
                      markup=True)


def print_written(*paths: object) -> None:
    """List files just written, on stderr (stdout carries only the results)."""
    for path in paths:
        click.echo(f"wrote {path}", err=True)


def print_timings(timings_s: dict[str, float]) -> None:
    """The stages' times, dim, on stdout (``Time: parse 0.004s, build 0.42s, ...``)."""
    text = ", ".join(f"{k} {v:.3f}s" for k, v in timings_s.items())
    print_dim(f"Time: {text}")


def print_warnings(warnings: Sequence[str]) -> None:
    """Print the model's warnings (deadlocks, nondeterminism) to stderr, the label
    yellow on a terminal.

    Off a terminal rich prints printable text unchanged, so it is echoed as is there,
    without importing rich (as :func:`print_dim`).
    """
    for warning in warnings:
        if warning.isprintable() and not _may_be_terminal(sys.stderr):
            click.echo(f"warning: {warning}", err=True)
        else:
            err.print(f"[yellow]warning:[/] {escape(warning)}", markup=True)


def check_modes(modes: Mapping[str, tuple[bool, Sequence[str]]]) -> None:
    """Refuse an option that only a mode not asked for reads: it would be ignored.

    :param modes: by the mode's option as typed (``--explain``, ``-o``), whether it is
        asked for and the parameter names of the options only it reads.
    :raises OptionError: naming the first such option given, and its mode.
    """
    context = click.get_current_context()
    for mode, (asked, names) in modes.items():
        for name in names:
            if not asked and context.get_parameter_source(name) == ParameterSource.COMMANDLINE:
                option = "--" + name.replace("_", "-")
                raise OptionError(f"{option} is read by {mode} only: give {mode}, or "
                                  f"leave out {option}")


def set_option(function: F) -> F:
    """The ``--set KEY=VALUE`` option of the mission commands."""
    return click.option(
        "--set", "overrides", multiple=True, metavar="KEY=VALUE",
        help="Override a config key (VALUE is YAML), e.g. --set farm.base=[1,1].",
    )(function)

