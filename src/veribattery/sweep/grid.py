"""Parameter grids from command-line ranges, like PRISM's experiments over constants.

An axis is one config key and the values it takes, written ``KEY=SPEC`` where SPEC is
either a range ``START:STOP:STEP`` (exact decimals; STOP is included when it lands on
the grid) or a comma list ``a,b,c`` (each item YAML, so ``battery.model=advanced,basic_high``
and ``farm.base=[0,0],[1,1]`` both work). The grid is the cartesian product of the axes.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction

import yaml

from veribattery._numbers import OutOfRange, count_text, exact_number
from veribattery.config import ConfigDocument, key_problem
from veribattery.config.exact import brief, fraction_to_decimal
from veribattery.config.source import NumberOutOfRange, compose, construct
from veribattery.errors import ConfigError, Span

__all__ = [
    "MAX_POINTS",
    "Axis",
    "Point",
    "axes_from",
    "check_sets",
    "grid",
    "parse_axis",
    "point_values",
    "yaml_text",
]

#: The most points one axis, or a whole grid, may have (a typo in STEP should not hang).
MAX_POINTS = 10_000

#: One grid point: config key → value, in axis order.
Point = dict[str, object]

_RANGE = re.compile(r"^[^,\[\]{}]*:[^,\[\]{}]*$")


@dataclass(frozen=True, slots=True)
class Axis:
    """One swept config key and its values, in sweep order."""

    key: str
    values: tuple[object, ...]


@dataclass(frozen=True, slots=True)
class _Origin:
    """Where a SPEC was given, to name it in errors: ``--vary 'KEY=SPEC'``, or a config's
    ``sweep.vary[0] 'KEY=SPEC'`` at its place in the file."""

    label: str
    span: Span | None = None

    def error(self, problem: str) -> ConfigError:
        return ConfigError(f"{self.label}: {problem}", self.span)


def parse_axis(text: str, origin: str | None = None, span: Span | None = None) -> Axis:
    """Parse ``KEY=START:STOP:STEP`` or ``KEY=a,b,c`` into an :class:`Axis`.

    :param text: the ``--vary`` argument (or an item of a config's ``sweep.vary``).
    :param origin: what errors call it (default: ``--vary 'TEXT'``).
    :param span: where it is written, for errors.
    :raises ConfigError: when the key is unknown or SPEC is malformed (one line, naming
        the option or config key and what is expected).
    """
    where = _Origin(origin or f"--vary {text!r}", span)
    key, sep, spec = text.partition("=")
    key, spec = key.strip(), spec.strip()
    if not sep or not key or not spec:
        raise where.error("expected KEY=START:STOP:STEP or KEY=a,b,c")
    _check_key(where, key)
    values = _range(where, spec) if _RANGE.match(spec) else _items(where, spec)
    return Axis(key, values)


def axes_from(specs: Sequence[str], config_vary: Sequence[str],
              document: ConfigDocument | None = None) -> list[Axis]:
    """The axes of ``--vary`` *specs*, or else of the config's ``sweep.vary`` list.

    :param document: the config as read, to place an error in a ``sweep.vary`` item at
        its line and column (or name the ``--set`` that gave it).
    :raises ConfigError: when there are none, a key is varied twice, or a SPEC is bad.
    """
    if not specs and not config_vary:
        raise ConfigError("nothing to sweep: give --vary KEY=SPEC, or a sweep.vary list in "
                          "the config")
    origins = ([_Origin(f"--vary {spec!r}") for spec in specs] if specs else
               [_config_origin(document, n, spec) for n, spec in enumerate(config_vary)])
    axes = [parse_axis(spec, where.label, where.span)
            for spec, where in zip(specs or config_vary, origins, strict=True)]
    keys = [axis.key for axis in axes]
    again = next((n for n, key in enumerate(keys) if key in keys[:n]), None)
    if again is not None:
        raise origins[again].error(f"key '{keys[again]}' is varied more than once")
    return axes


def check_sets(axes: Sequence[Axis], overrides: Sequence[str], varied_by: str) -> None:
    """Refuse a ``--set`` of a key the grid varies (or of a key inside it): each point's
    value would replace it, and the ``--set`` would be dropped without a word.

    :param overrides: the ``--set`` strings, as typed.
    :param varied_by: what gives the axes, for the message (``--vary``).
    :raises ConfigError: naming the ``--set`` as typed and the varied key.
    """
    for item in overrides:
        key = item.partition("=")[0].strip()
        axis = next((a for a in axes if key == a.key or key.startswith(f"{a.key}.")), None)
        if axis is not None:
            raise ConfigError(f"--set {item}: {axis.key} is also varied by {varied_by}; "
                              "drop one")


def _config_origin(document: ConfigDocument | None, index: int, spec: str) -> _Origin:
    """``sweep.vary[INDEX]`` where the file has it, or the ``--set`` that gave it."""
    key = f"sweep.vary[{index}] {spec!r}"
    span = document.span_of(("sweep", "vary", index)) if document is not None else None
    from_set = document is not None and span is None
    return _Origin(f"--set {key}" if from_set else key, span)


def grid(axes: Sequence[Axis]) -> list[Point]:
    """The cartesian product of *axes*, the first axis varying slowest.

    :raises ConfigError: when a key is swept twice or the grid has too many points.
    """
    keys = [axis.key for axis in axes]
    twice = sorted({key for key in keys if keys.count(key) > 1})
    if twice:
        raise ConfigError(f"--vary: key '{twice[0]}' is varied more than once")
    size = 1
    for axis in axes:
        size *= len(axis.values)
    if size > MAX_POINTS:
        raise ConfigError(f"--vary: the grid has {size:,} points (at most {MAX_POINTS:,})")
    return [dict(zip(keys, combo, strict=True)) for combo in
            itertools.product(*(axis.values for axis in axes))]


def point_values(point: Mapping[str, object]) -> dict[str, object]:
    """The values one grid point sets, by dotted key, as YAML loads them (lists where the
    grid holds tuples): what :meth:`~veribattery.config.ConfigDocument.with_values` takes."""
    return {key: _thaw(value) for key, value in point.items()}


def yaml_text(value: object) -> str:
    """*value* as one line of YAML flow text that loads back to an equal value."""
    text: str = yaml.safe_dump(_thaw(value), default_flow_style=True, width=10**9)
    return text.removesuffix("\n").removesuffix("\n...").strip()


def _check_key(where: _Origin, key: str) -> None:
    problem = key_problem(key)
    if problem is not None:
        raise where.error(problem)


def _range(where: _Origin, spec: str) -> tuple[object, ...]:
    """``START:STOP:STEP`` with exact decimal arithmetic; STOP included when on the grid."""
    parts = spec.split(":")
    if len(parts) != 3:
        raise where.error(f"range {spec!r} must be START:STOP:STEP, e.g. 10:13:0.5")
    start, stop, step = (_decimal(where, part) for part in parts)
    if step <= 0:
        raise where.error(f"STEP must be > 0, got {parts[2].strip()}")
    if stop < start:
        raise where.error(f"STOP must be ≥ START, got {parts[0].strip()}:{parts[1].strip()}")
    count = int((stop - start) // step) + 1
    if count > MAX_POINTS:
        raise where.error(f"range gives {count_text(count)} values (at most {MAX_POINTS:,})")
    return tuple(_number(where, start + k * step) for k in range(count))


def _decimal(where: _Origin, part: str) -> Fraction:
    try:
        if "/" not in part:
            return exact_number(part)
    except OutOfRange as exc:
        raise where.error(str(exc)) from None
    except ValueError:
        pass
    raise where.error(f"{brief(part.strip())} is not a decimal number (START:STOP:STEP)")


def _number(where: _Origin, value: Fraction) -> int | float:
    """An int when whole, else the float whose repr is the exact decimal."""
    if value.denominator == 1:
        return value.numerator
    decimal = fraction_to_decimal(value)
    number = float(decimal) if decimal is not None else float("nan")
    if decimal is None or repr(number) != decimal.removeprefix("+"):
        raise where.error(f"value {decimal or value} has more digits than a float holds")
    return number


def _items(where: _Origin, spec: str) -> tuple[object, ...]:
    """``a,b,c``: the items of a YAML flow sequence, so ``[0,0],[1,1]`` is two lists (read
    as a config's values are: ``010`` is not the octal eight)."""
    flow = f"[{spec}]"
    try:
        items = construct(compose(flow, None), flow, None)
    except NumberOutOfRange as exc:
        raise where.error(exc.reason) from None
    except ConfigError:
        items = None
    if not isinstance(items, list) or not items or any(item is None for item in items):
        raise where.error(f"{spec!r} is not START:STOP:STEP or a comma list of YAML values a,b,c")
    frozen = tuple(_freeze(item) for item in items)
    twice = next((item for n, item in enumerate(frozen) if item in frozen[:n]), None)
    if twice is not None:
        raise where.error(f"{_thaw(twice)!r} is given twice (each point runs once)")
    return frozen


def _freeze(value: object) -> object:
    """Lists as tuples (recursively), so grid values are hashable DataFrame cells."""
    return tuple(_freeze(v) for v in value) if isinstance(value, list) else value


def _thaw(value: object) -> object:
    return [_thaw(v) for v in value] if isinstance(value, tuple) else value
