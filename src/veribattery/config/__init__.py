"""Mission configs: YAML → :class:`MissionConfig` → derived grid, battery and model numbers.

This package imports nothing of veribattery but :mod:`veribattery.errors` and the base
modules that read the user's text (``_text``) and numbers (``_numbers``).
"""

from veribattery.config.battery import CostTable, capacity_units, consumption_units, round_half_up
from veribattery.config.farm import FarmLayout, derive_layout, route_cells
from veribattery.config.load import (
    ConfigDocument,
    config_to_yaml,
    key_problem,
    load_config,
    parse_override,
    read_config,
    require_config,
    set_value,
)
from veribattery.config.params import ModelParameters, Ratio, derive_parameters
from veribattery.config.requirement import requirement_problem
from veribattery.config.schema import MissionConfig, Requirement, parse_requirement
from veribattery.config.validate import known_keys, validate_config

__all__ = [
    "ConfigDocument",
    "CostTable",
    "FarmLayout",
    "MissionConfig",
    "ModelParameters",
    "Ratio",
    "Requirement",
    "capacity_units",
    "config_to_yaml",
    "consumption_units",
    "derive_layout",
    "derive_parameters",
    "key_problem",
    "known_keys",
    "load_config",
    "parse_override",
    "parse_requirement",
    "read_config",
    "require_config",
    "requirement_problem",
    "round_half_up",
    "route_cells",
    "set_value",
    "validate_config",
]
