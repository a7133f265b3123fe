"""Config values from fits: exact decimals on the config's grids, as YAML or ``--set`` text.

A :class:`Fragment` is an ordered map of dotted config keys (``battery.capacity_ah``)
to values — exact :class:`~fractions.Fraction` decimals, or nested mappings of them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction

from veribattery.config import MissionConfig, capacity_units
from veribattery.config.exact import fraction_to_decimal
from veribattery.config.params import PRISM_INT_MAX

__all__ = ["Fragment", "block_yaml", "decimal", "fade_value", "on_grid", "to_yaml_value"]

#: Significant digits kept of a fitted fade rate (its CI is far wider than this).
FADE_DIGITS = 3


@dataclass(frozen=True, slots=True)
class Fragment:
    """Config keys (dotted) and the values to give them, in order."""

    values: dict[str, object]

    def yaml(self) -> str:
        """The fragment as nested block YAML."""
        tree: dict[str, object] = {}
        for key, value in self.values.items():
            node = tree
            *parents, leaf = key.split(".")
            for part in parents:
                node = node.setdefault(part, {})  # type: ignore[assignment]
            node[leaf] = value
        return block_yaml(tree, 0)

    def overrides(self) -> list[str]:
        """The fragment as ``KEY=VALUE`` strings for :func:`veribattery.config.load_config`."""
        return [f"{key}={to_yaml_value(value)}" for key, value in self.values.items()]


def block_yaml(value: object, indent: int) -> str:
    """*value* as block YAML at *indent* (a scalar as one line)."""
    if not isinstance(value, Mapping):
        return f"{to_yaml_value(value)}\n"
    lines = []
    for key, item in value.items():
        if isinstance(item, Mapping):
            lines.append(f"{' ' * indent}{key}:\n{block_yaml(item, indent + 2)}")
        else:
            lines.append(f"{' ' * indent}{key}: {to_yaml_value(item)}\n")
    return "".join(lines)


def to_yaml_value(value: object) -> str:
    """A value as YAML text: fractions as exact decimals, mappings in flow style."""
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k}: {to_yaml_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, Fraction):
        text = fraction_to_decimal(value)
        return text if text is not None else f"'{value}'"
    return str(value)


def decimal(value: float, places: int) -> Fraction:
    """*value* rounded half-even to *places* decimals, as an exact fraction."""
    return Fraction(Decimal(repr(value)).quantize(Decimal(1).scaleb(-places)))


def on_grid(value_ah: float, resolution: Fraction) -> Fraction:
    """The multiple of *resolution* nearest to *value_ah* (at least one unit)."""
    units = max(1, math.floor(Fraction(repr(value_ah)) / resolution + Fraction(1, 2)))
    return units * resolution


def fade_value(fade: float, cfg: MissionConfig, capacity_ah: Fraction) -> Fraction:
    """*fade* to :data:`FADE_DIGITS` significant digits, as an exact decimal.

    Fewer digits are kept if the model's ``C_NEW x denominator`` would leave PRISM's
    32-bit integers (the config layer refuses such fades), and a negative or zero
    fade is 0.
    """
    if fade <= 0:
        return Fraction(0)
    c_new = capacity_units(cfg.battery.model_copy(update={"capacity_ah": capacity_ah}))
    places = FADE_DIGITS - 1 - math.floor(math.log10(fade))
    while places > 0 and c_new * 10**places > PRISM_INT_MAX // 2:
        places -= 1
    return decimal(fade, places)
