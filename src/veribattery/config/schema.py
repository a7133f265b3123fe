"""The mission config: frozen pydantic models whose defaults are the paper's baseline.

An empty YAML file validates to the paper's setting (6 x 6 turbines, 11 Ah, advanced
battery, ``safe_t`` 0.3, ``p_wsp_c`` 0.1). Every decimal a user writes (thresholds,
fade, capacity, resolution, times) is kept as an exact :class:`~fractions.Fraction`:
YAML hands us binary floats, and ``Fraction(repr(x))`` recovers the decimal as written.

Validation problems are reported by :func:`validate_config` as one-line
:class:`~veribattery.errors.ConfigError` messages that name the dotted key path.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from fractions import Fraction
from typing import Annotated, Any, Literal, Self

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    PrivateAttr,
    StrictInt,
    Tag,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from veribattery.config.exact import Exact, brief, problem
from veribattery.config.origin import PropertyOrigins
from veribattery.config.place import KeyOrigins
from veribattery.config.requirement import (
    Requirement,
    is_property_name,
    parse_requirement,
    requirement_problem,
)
from veribattery.errors import ConfigError, Span

__all__ = [
    "MAX_TURBINES",
    "RECHARGE_CAP_PROPERTY",
    "RESERVED_PROPERTY_NAMES",
    "BatteryConfig",
    "Cell",
    "ConsumptionEq2",
    "ConsumptionTable",
    "EnvironmentConfig",
    "FarmConfig",
    "LevelValues",
    "MissionConfig",
    "Requirement",
    "StrategyConfig",
    "SweepConfig",
    "TimesConfig",
    "is_property_name",
    "parse_requirement",
]

Cell = tuple[int, int]
BatteryModel = Literal["advanced", "basic_high", "basic_medium", "basic_low"]
RouteName = Literal["snake_rows", "snake_columns"]
StrategyMode = Literal["bs1", "synthesize"]

#: The name under which ``check`` reports P[F rc=RC_MAX] beside the config's properties
#: (a last CSV row, a JSON key): a property of that name would give two rows of one name.
RECHARGE_CAP_PROPERTY = "recharge_cap_probability"
RESERVED_PROPERTY_NAMES = frozenset({RECHARGE_CAP_PROPERTY})

PAPER_PROPERTIES: dict[str, str] = {
    "p_success": 'P=? [ F "success" ]',
    "exp_mission_time": 'R{"mt"}=? [ F "done" ]',
    "exp_recharges": 'R{"rc"}=? [ F "done" ]',
    # Storm's conditional operator: the expectations given that the mission succeeds.
    "exp_mission_time_given_success": 'R{"mt"}=? [ F "done" || F "success" ]',
    "exp_recharges_given_success": 'R{"rc"}=? [ F "done" || F "success" ]',
}


def _to_cell(value: object) -> Cell:
    """A cell ``[x, y]`` of two integers."""
    if isinstance(value, list | tuple) and len(value) == 2:
        x, y = value
        if _is_int(x) and _is_int(y):
            return (x, y)
    raise problem(f"must be a cell [x, y] of two integers, got {brief(value)}")


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _to_route(value: object) -> RouteName | tuple[Cell, ...]:
    """A route name, or an explicit list of cells."""
    if value == "snake_rows" or value == "snake_columns":
        return value
    if isinstance(value, list | tuple) and value:
        try:
            return tuple(_to_cell(c) for c in value)
        except PydanticCustomError:
            pass
    raise problem(
        "must be 'snake_rows', 'snake_columns' or a list of cells [x, y], " f"got {brief(value)}"
    )


CellField = Annotated[Cell, BeforeValidator(_to_cell)]
RouteField = Annotated[RouteName | tuple[Cell, ...], BeforeValidator(_to_route)]


def _check_range(value: Fraction, low: Fraction | None, high: Fraction | None, text: str) -> None:
    """Raise ``must be <text>, got v`` unless low < value < high (bounds exclusive when given)."""
    if (low is not None and value <= low) or (high is not None and value >= high):
        raise problem(f"must be {text}, got {brief(value)}")


def _positive(value: Fraction) -> Fraction:
    _check_range(value, Fraction(0), None, "> 0")
    return value


#: An exact number that must be > 0 (capacities, times, energies, factors).
Positive = Annotated[Exact, AfterValidator(_positive)]


class _Section(BaseModel):
    """Every config section: immutable, unknown keys rejected; a sub-section given in part
    takes its other keys from its default."""

    model_config = ConfigDict(
        extra="forbid", frozen=True, arbitrary_types_allowed=True, validate_default=False
    )

    @model_validator(mode="before")
    @classmethod
    def _partial_sections(cls, data: Any) -> Any:
        """``cell: {low: 0.6}`` keeps the default cell's ``medium`` and ``high``: every key
        is optional, as an empty file is the baseline. (A mapping with keys the default's
        kind lacks, such as Eq. 2's in ``consumption``, is left to its own kind.)"""
        if not isinstance(data, dict):
            return data
        merged = dict(data)
        for name, field in cls.model_fields.items():
            default, given = field.default, data.get(name)
            if (isinstance(default, BaseModel) and isinstance(given, Mapping)
                    and set(given) <= set(type(default).model_fields)):
                merged[name] = {**dict(default), **given}
        return merged


#: The most turbines a farm may have (a 300 x 300 farm is emitted in about 20 s).
MAX_TURBINES = 100_000


class FarmConfig(_Section):
    """The wind farm: a lattice of ``cols x rows`` turbines and the cells between them."""

    cols: StrictInt = 6
    rows: StrictInt = 6
    spacing_m: Positive = Fraction(500)
    base: CellField = (2, 2)
    route: RouteField = "snake_rows"

    @field_validator("cols", "rows")
    @classmethod
    def _at_least_two(cls, value: int) -> int:
        if value < 2:
            raise problem(f"must be at least 2 turbines, got {value}")
        return value

    @property
    def cells(self) -> tuple[int, int]:
        """Number of cells across and up: one fewer than the turbines."""
        return (self.cols - 1, self.rows - 1)

    @model_validator(mode="after")
    def _cells_fit(self) -> Self:
        size = f"{self.cols} x {self.rows} turbines"
        if self.cols * self.rows > MAX_TURBINES:  # else deriving the route takes forever
            too_large = f"{size} is too large a farm: cols x rows must be at most {MAX_TURBINES:,}"
            raise problem(too_large, "cols", (("rows", too_large),))
        if not self._inside(self.base):
            raise self._outside("base", self.base)
        if isinstance(self.route, tuple):
            self._check_route(self.route)
        return self

    def _outside(self, key: str, cell: Cell) -> PydanticCustomError:
        """*cell* of *key* lies outside the farm: *key*'s fault, or cols' or rows'."""
        size = f"{self.cols} x {self.rows} turbines leave"
        sized = f"{size} farm.{key}'s cell {brief(cell)} outside the {self._extent()}"
        return problem(f"cell {brief(cell)} is outside the {self._extent()}", key,
                       (("cols", sized), ("rows", sized)))

    def _inside(self, cell: Cell) -> bool:
        return 0 <= cell[0] < self.cols - 1 and 0 <= cell[1] < self.rows - 1

    def _extent(self) -> str:
        cx, cy = self.cells
        return f"{cx} x {cy} cells (x in 0..{cx - 1}, y in 0..{cy - 1})"

    def _check_route(self, route: tuple[Cell, ...]) -> None:
        seen: set[Cell] = set()
        for cell in route:
            if not self._inside(cell):
                raise self._outside("route", cell)
            if cell in seen:
                raise problem(f"cell {brief(cell)} appears twice", "route")
            seen.add(cell)
        missing = [(x, y) for y in range(self.rows - 1) for x in range(self.cols - 1)]
        missing = [c for c in missing if c not in seen]
        if missing:
            sized = (f"{self.cols} x {self.rows} turbines have cell {brief(missing[0])} that "
                     f"farm.route misses ({len(missing)} missing)")
            raise problem(f"misses cell {brief(missing[0])} ({len(missing)} missing)", "route",
                          (("cols", sized), ("rows", sized)))


class LevelValues(_Section):
    """One value per voltage level."""

    low: Positive
    medium: Positive
    high: Positive



class ConsumptionTable(_Section):
    """Table 2 of the paper (Ah per action at low wind) and the high-wind factor."""

    takeoff_land: LevelValues = LevelValues(
        low=Fraction(3, 10), medium=Fraction(2, 10), high=Fraction(1, 10)
    )
    cell: LevelValues = LevelValues(
        low=Fraction(5, 10), medium=Fraction(4, 10), high=Fraction(3, 10)
    )
    inspection: LevelValues = LevelValues(
        low=Fraction(45, 10), medium=Fraction(40, 10), high=Fraction(36, 10)
    )
    high_wind_factor: Positive = Fraction(2)



class WindValues(_Section):
    """One value per wind level (power demand level of BA2)."""

    low_wind: Positive
    high_wind: Positive



class ActionValues(_Section):
    """One value per kind of action."""

    takeoff_land: Positive
    cell: Positive
    inspection: Positive



class ConsumptionEq2(_Section):
    """Eq. 2's physical parameters, ``C = E_spec·t / (V·T)``; the table is computed from them."""

    energy_wh: Positive = Fraction(180)
    voltages_v: LevelValues = LevelValues(
        low=Fraction(20), medium=Fraction(22), high=Fraction(25)
    )
    flight_time_h: WindValues = WindValues(low_wind=Fraction(1, 2), high_wind=Fraction(1, 4))
    action_time_h: ActionValues = ActionValues(
        takeoff_land=Fraction(1, 60), cell=Fraction(2, 60), inspection=Fraction(1, 4)
    )



_EQ2_KEYS = frozenset(ConsumptionEq2.model_fields)


def _consumption_kind(value: object) -> str:
    """``eq2`` when any of Eq. 2's keys is given, else the table."""
    keys = value.keys() if isinstance(value, Mapping) else ()
    if isinstance(value, ConsumptionEq2) or _EQ2_KEYS.intersection(keys):
        return "eq2"
    return "table"


Consumption = Annotated[
    Annotated[ConsumptionTable, Tag("table")] | Annotated[ConsumptionEq2, Tag("eq2")],
    Discriminator(_consumption_kind),
]
UNION_TAGS = frozenset({"table", "eq2"})


class VoltageThresholds(_Section):
    """SOC bounds of the voltage levels (BA3): high above ``high``, low below ``low``."""

    high: Exact = Fraction(3, 4)
    low: Exact = Fraction(1, 4)

    @field_validator("high", "low")
    @classmethod
    def _unit_interval(cls, value: Fraction) -> Fraction:
        _check_range(value, Fraction(0), Fraction(1), "in (0, 1)")
        return value

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        low, high = brief(self.low), brief(self.high)
        if self.low > self.high:
            raise problem(f"must be <= high ({high}), got {low}", "low",
                          (("high", f"must be >= low ({low}), got {high}"),))
        return self


class BatteryConfig(_Section):
    """The battery: model variant, capacity, resolution, fade and consumption."""

    model: BatteryModel = "advanced"
    capacity_ah: Positive = Fraction(11)
    resolution_ah: Positive = Fraction(1, 10)
    fade_per_recharge: Exact = Fraction(2, 1000)
    max_recharges: StrictInt = 200
    voltage_thresholds: VoltageThresholds = VoltageThresholds()
    consumption: Consumption = ConsumptionTable()


    @field_validator("fade_per_recharge")
    @classmethod
    def _fade(cls, value: Fraction) -> Fraction:
        if not 0 <= value < 1:
            raise problem(f"must be in [0, 1), got {brief(value)}")
        return value

    @field_validator("max_recharges")
    @classmethod
    def _recharges(cls, value: int) -> int:
        if value < 0:
            raise problem(f"must be >= 0, got {value}")
        return value

    @model_validator(mode="after")
    def _whole_units(self) -> Self:
        capacity, resolution = brief(self.capacity_ah), brief(self.resolution_ah)
        if (self.capacity_ah / self.resolution_ah).denominator != 1:
            raise problem(
                f"must be a whole number of resolution_ah ({resolution}) units, got {capacity}",
                "capacity_ah", (("resolution_ah", f"must divide capacity_ah ({capacity}) into "
                                f"whole units, got {resolution}"),))
        fade, most = self.fade_per_recharge, self.max_recharges
        if self.model == "advanced" and fade * most >= 1:
            raise problem(
                f"fade_per_recharge x max_recharges must be < 1 so the capacity stays "
                f"positive, got {brief(fade)} x {brief(most)}", "fade_per_recharge",
                (("max_recharges", f"must be at most {math.ceil(1 / fade) - 1} so that "
                  f"fade_per_recharge ({brief(fade)}) x max_recharges stays < 1 (the capacity "
                  f"positive), got {brief(most)}"),))
        return self

    @property
    def fade(self) -> Fraction:
        """The fade actually modelled: basic models have none."""
        return self.fade_per_recharge if self.model == "advanced" else Fraction(0)


def _is_bs1(mode: str) -> bool:
    return mode == "bs1"


class StrategyConfig(_Section):
    """The drone's return policy: the battery safety strategy BS1, or synthesised."""

    safe_t: Exact = Fraction(3, 10)
    #: ``bs1``: the paper's DTMC, every decision taken by BS1; ``synthesize``: the MDP of
    #: model-spec.md ("Synthesis"), every decision left open. The resolved config leaves
    #: the default out, so that BS1's emitted files and sweep keys stay as they were.
    mode: StrategyMode = Field("bs1", exclude_if=_is_bs1)

    @field_validator("safe_t")
    @classmethod
    def _unit_interval(cls, value: Fraction) -> Fraction:
        _check_range(value, Fraction(0), Fraction(1), "in (0, 1)")
        return value


class EnvironmentConfig(_Section):
    """The wind: probability that it changes level at each drone action (EA2)."""

    p_wsp_c: Exact = Fraction(1, 10)

    @field_validator("p_wsp_c")
    @classmethod
    def _probability(cls, value: Fraction) -> Fraction:
        if not 0 <= value <= 1:
            raise problem(f"must be in [0, 1], got {brief(value)}")
        return value


class TimesConfig(_Section):
    """Minutes per action: the ``mt`` reward."""

    takeoff_land: Exact = Fraction(1)
    per_cell: Exact = Fraction(2)
    inspection: Exact = Fraction(15)
    recharge: Exact = Fraction(90)
    wait: Exact = Fraction(0)

    @field_validator("*")
    @classmethod
    def _non_negative(cls, value: Fraction) -> Fraction:
        if value < 0:
            raise problem(f"must be >= 0, got {brief(value)}")
        return value


class SweepConfig(_Section):
    """A parameter sweep (``veribattery sweep``): the ``--vary`` SPECs, first varying slowest."""

    vary: tuple[str, ...] = ()


class MissionConfig(_Section):
    """A whole mission: farm, battery, strategy, environment, times, properties, requirements."""

    farm: FarmConfig = FarmConfig()
    battery: BatteryConfig = BatteryConfig()
    strategy: StrategyConfig = StrategyConfig()
    environment: EnvironmentConfig = EnvironmentConfig()
    times_min: TimesConfig = TimesConfig()
    properties: dict[str, str] = Field(default_factory=lambda: dict(PAPER_PROPERTIES))
    requirements: tuple[str, ...] = ()
    sweep: SweepConfig = SweepConfig()
    #: Where the property formulas were written (set by load_config; not compared).
    _property_origins: PropertyOrigins = PrivateAttr(default_factory=PropertyOrigins)
    #: Where every key was given (set by load_config; not compared).
    _key_origins: KeyOrigins = PrivateAttr(default_factory=KeyOrigins)

    @field_validator("properties")
    @classmethod
    def _named(cls, value: dict[str, str]) -> dict[str, str]:
        for name, text in value.items():
            if not is_property_name(name):
                raise problem(f"property name must be an identifier, got {brief(name)}")
            if name in RESERVED_PROPERTY_NAMES:
                raise problem(f"property name {name!r} is reserved: check reports "
                              "P[F rc=RC_MAX] under it; choose another name", name)
            if not text.strip():
                raise problem(f"property {name!r} has an empty formula")
        return value

    @model_validator(mode="after")
    def _requirements_named(self) -> Self:
        for i, text in enumerate(self.requirements):
            try:
                req = parse_requirement(text)
            except ValueError as exc:
                raise problem(str(exc), f"requirements.{i}") from None
            if req.prop not in self.properties:
                names = ", ".join(self.properties) or "none"
                raise problem(
                    f"unknown property {req.prop!r} (declared: {names})", f"requirements.{i}"
                )
            wrong = requirement_problem(req, self.properties[req.prop], self.properties)
            if wrong is not None:
                raise problem(wrong, f"requirements.{i}")
        return self

    def key_error(self, *blames: tuple[str, str]) -> ConfigError:
        """A :class:`ConfigError` about a problem that changing any of *blames*' dotted
        keys would fix (each ``(key, message)``): it names the one the user gave, placed
        in the file or at its ``--set`` (see :class:`~veribattery.config.place.KeyOrigins`).
        """
        return self._key_origins.error(blames)

    def property_error(self, name: str, message: str, at: Span | None = None) -> ConfigError:
        """A :class:`ConfigError` for a problem *at* a line:col of property *name*'s
        formula, placed where the formula was written: its file position, or the
        ``--set`` it came from (for a config built in code, the key alone)."""
        return self._property_origins.error(name, self.properties[name], message, at)

    def require_bs1(self) -> None:
        """Refuse to go on with BS1's DTMC when the config asks for synthesis.

        :raises ConfigError: when ``strategy.mode`` is ``synthesize``.
        """
        if self.strategy.mode == "synthesize":
            raise ConfigError(
                "strategy.mode: synthesize makes the mission an MDP, and this command verifies "
                "BS1's DTMC: use `veribattery synthesize CONFIG` (or `veribattery emit` for "
                "Storm or PRISM), or set strategy.mode=bs1")

    @property
    def parsed_requirements(self) -> tuple[Requirement, ...]:
        """The requirements, parsed."""
        return tuple(parse_requirement(t) for t in self.requirements)
