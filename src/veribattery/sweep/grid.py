"""Parameter grids from command-line ranges, like PRISM's experiments over constants.

An axis is one config key and the values it takes, written ``KEY=SPEC`` where SPEC is
either a range ``START:STOP:STEP`` (exact decimals; STOP is included when it lands on
the grid) or a comma list ``a,b,c`` (each item YAML, so ``battery.model=advanced,basic_high``
and ``farm.base=[0,0],[1,1]`` both work). The grid is the cartesian product of the axes.
"""

from __future__ import annotations

import difflib
import itertools
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction

import yaml

from veribattery._numbers import OutOfRange, count_text, exact_number
from veribattery.config import known_keys
from veribattery.config.exact import brief, fraction_to_decimal
from veribattery.config.schema import is_property_name
from veribattery.config.source import NumberOutOfRange, compose, construct
from veribattery.errors import ConfigError

__all__ = [
    "MAX_POINTS",
    "Axis",
    "Point",
    "axes_from",
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
_PROPERTY_KEY = "properties."


@dataclass(frozen=True, slots=True)
class Axis:
    """One swept config key and its values, in sweep order."""

    key: str
    values: tuple[object, ...]


def parse_axis(text: str) -> Axis:
    """Parse ``KEY=START:STOP:STEP`` or ``KEY=a,b,c`` into an :class:`Axis`.

    :param text: the ``--vary`` argument.
    :raises ConfigError: when the key is unknown or SPEC is malformed (one line, naming
        the option and what is expected).
    """
    key, sep, spec = text.partition("=")
    key, spec = key.strip(), spec.strip()
    if not sep or not key or not spec:
        raise _bad(text, "expected KEY=START:STOP:STEP or KEY=a,b,c")
    _check_key(text, key)
    values = _range(text, spec) if _RANGE.match(spec) else _items(text, spec)
    return Axis(key, values)


def axes_from(specs: Sequence[str], config_vary: Sequence[str]) -> list[Axis]:
    """The axes of ``--vary`` *specs*, or else of the config's ``sweep.vary`` list.

    :raises ConfigError: when there are none, or a SPEC is bad.
    """
    chosen = specs or config_vary
    if not chosen:
        raise ConfigError("nothing to sweep: give --vary KEY=SPEC, or a sweep.vary list in "
                          "the config")
    return [parse_axis(spec) for spec in chosen]


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


def _bad(text: str, expected: str) -> ConfigError:
    return ConfigError(f"--vary {text!r}: {expected}")


def _check_key(text: str, key: str) -> None:
    if key.startswith(_PROPERTY_KEY):
        name = key.removeprefix(_PROPERTY_KEY)
        if is_property_name(name):
            return
        raise _bad(text, f"property name {name!r} must be an identifier (letters, digits "
                         "and _, not starting with a digit)")
    if key in known_keys():
        return
    close = difflib.get_close_matches(key, known_keys(), n=1, cutoff=0.6)
    hint = f"did you mean '{close[0]}'?" if close else "see configs/example.yaml for the keys"
    raise _bad(text, f"unknown key '{key}' ({hint})")


def _range(text: str, spec: str) -> tuple[object, ...]:
    """``START:STOP:STEP`` with exact decimal arithmetic; STOP included when on the grid."""
    parts = spec.split(":")
    if len(parts) != 3:
        raise _bad(text, f"range {spec!r} must be START:STOP:STEP, e.g. 10:13:0.5")
    start, stop, step = (_decimal(text, part) for part in parts)
    if step <= 0:
        raise _bad(text, f"STEP must be > 0, got {parts[2].strip()}")
    if stop < start:
        raise _bad(text, f"STOP must be ≥ START, got {parts[0].strip()}:{parts[1].strip()}")
    count = int((stop - start) // step) + 1
    if count > MAX_POINTS:
        raise _bad(text, f"range gives {count_text(count)} values (at most {MAX_POINTS:,})")
    return tuple(_number(text, start + k * step) for k in range(count))


def _decimal(text: str, part: str) -> Fraction:
    try:
        if "/" not in part:
            return exact_number(part)
    except OutOfRange as exc:
        raise _bad(text, str(exc)) from None
    except ValueError:
        pass
    raise _bad(text, f"{brief(part.strip())} is not a decimal number (START:STOP:STEP)")


def _number(text: str, value: Fraction) -> int | float:
    """An int when whole, else the float whose repr is the exact decimal."""
    if value.denominator == 1:
        return value.numerator
    decimal = fraction_to_decimal(value)
    number = float(decimal) if decimal is not None else float("nan")
    if decimal is None or repr(number) != decimal.removeprefix("+"):
        raise _bad(text, f"value {decimal or value} has more digits than a float holds")
    return number


def _items(text: str, spec: str) -> tuple[object, ...]:
    """``a,b,c``: the items of a YAML flow sequence, so ``[0,0],[1,1]`` is two lists (read
    as a config's values are: ``010`` is not the octal eight)."""
    flow = f"[{spec}]"
    try:
        items = construct(compose(flow, None), flow, None)
    except NumberOutOfRange as exc:
        raise _bad(text, exc.reason) from None
    except ConfigError:
        items = None
    if not isinstance(items, list) or not items or any(item is None for item in items):
        raise _bad(text, f"{spec!r} is not START:STOP:STEP or a comma list of YAML values a,b,c")
    frozen = tuple(_freeze(item) for item in items)
    twice = next((item for n, item in enumerate(frozen) if item in frozen[:n]), None)
    if twice is not None:
        raise _bad(text, f"{_thaw(twice)!r} is given twice (each point runs once)")
    return frozen


def _freeze(value: object) -> object:
    """Lists as tuples (recursively), so grid values are hashable DataFrame cells."""
    return tuple(_freeze(v) for v in value) if isinstance(value, list) else value


def _thaw(value: object) -> object:
    return [_thaw(v) for v in value] if isinstance(value, tuple) else value
