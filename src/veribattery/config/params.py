"""Every number the PRISM model needs, derived from a config as plain data.

The template lays these out and computes nothing: guards are integer
comparisons whose coefficients (:class:`Ratio`) are chosen here, per-cell values
come as runs over ``k``, costs come in units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

from veribattery.config.battery import FIXED_LEVEL, CostTable, capacity_units, consumption_units
from veribattery.config.exact import show
from veribattery.config.farm import FarmLayout, derive_layout
from veribattery.config.limits import PRISM_INT_MAX, check_int_ranges
from veribattery.config.schema import MissionConfig

__all__ = ["J_MAX", "PRISM_INT_MAX", "ModelParameters", "Ratio", "Run", "derive_parameters", "runs"]

#: Largest value of ``j``: a cell has at most four turbines at its corners.
J_MAX = 4


@dataclass(frozen=True, slots=True)
class Ratio:
    """An exact fraction ``num/den`` used as integer coefficients in a guard."""

    num: int
    den: int

    @classmethod
    def of(cls, value: Fraction, den: int | None = None) -> Ratio:
        """*value* as ``num/den``, over *den* when given (it must be a multiple)."""
        den = value.denominator if den is None else den
        return cls(value.numerator * (den // value.denominator), den)

    @property
    def text(self) -> str:
        """The value as the user wrote it, for comments."""
        return show(Fraction(self.num, self.den))


@dataclass(frozen=True, slots=True)
class Run:
    """Route cells ``first..last`` share *value* (keeps nested ``?:`` over ``k`` short)."""

    first: int
    last: int
    value: int


def runs(values: tuple[int, ...]) -> tuple[Run, ...]:
    """Group equal neighbours of *values* (indexed by ``k``) into runs."""
    out: list[Run] = []
    for k, value in enumerate(values):
        if out and out[-1].value == value:
            out[-1] = Run(out[-1].first, k, value)
        else:
            out.append(Run(k, k, value))
    return tuple(out)


@dataclass(frozen=True, slots=True)
class ModelParameters:
    """The plain data the model template lays out.

    :ivar model: the battery variant (``advanced`` or ``basic_*``).
    :ivar fixed_level: the voltage level of a basic model (0 low, 1 medium, 2 high), else None.
    :ivar resolution: ``resolution_ah`` as text, for comments.
    :ivar capacity_ah: the new capacity as text, for comments.
    :ivar c_new: new capacity in units.
    :ivar rc_max: recharges allowed.
    :ivar fade: capacity lost per recharge (0 for basic models).
    :ivar v_high: SOC above which the voltage is high, over a denominator shared with v_low.
    :ivar v_low: SOC below which the voltage is low.
    :ivar safe: ``safe_t``.
    :ivar costs: units per action, ``[wind][level]``.
    :ivar cost_source: how the table was obtained, for comments.
    :ivar layout: the farm grid.
    :ivar n_runs: runs of ``n`` over ``k``.
    :ivar dist_runs: runs of ``dist`` over ``k``.
    :ivar step_runs: runs of ``step`` over ``k``.
    :ivar p_wsp_c: probability that the wind changes at a drone action.
    :ivar times: minutes per action kind (``takeoff_land``, ``per_cell``, ...).
    """

    model: str
    fixed_level: int | None
    resolution: str
    capacity_ah: str
    c_new: int
    rc_max: int
    fade: Ratio
    v_high: Ratio
    v_low: Ratio
    safe: Ratio
    costs: CostTable
    cost_source: str
    layout: FarmLayout
    n_runs: tuple[Run, ...]
    dist_runs: tuple[Run, ...]
    step_runs: tuple[Run, ...]
    p_wsp_c: Fraction
    times: dict[str, Fraction]

    @property
    def num_cells(self) -> int:
        """``K``."""
        return self.layout.num_cells

    @property
    def j_max(self) -> int:
        """Upper bound of ``j``."""
        return J_MAX


def _cost_source(cfg: MissionConfig) -> str:
    consumption = cfg.battery.consumption
    if hasattr(consumption, "high_wind_factor"):
        factor = show(consumption.high_wind_factor)
        return f"Table 2 at low wind; high wind = low-wind units x {factor}, rounded half up"
    return "Eq. 2, C = E_spec·t / (V·T), for each wind and level, rounded half up"


def derive_parameters(cfg: MissionConfig) -> ModelParameters:
    """Derive the template's data from a validated config.

    :raises ConfigError: when the numbers would overflow PRISM's integers.
    """
    battery = cfg.battery
    layout = derive_layout(cfg.farm)
    fade = Ratio.of(battery.fade)
    c_new = capacity_units(battery)
    costs = consumption_units(battery)
    check_int_ranges(cfg, c_new, costs, layout)
    thresholds = battery.voltage_thresholds
    den = math.lcm(thresholds.high.denominator, thresholds.low.denominator)
    return ModelParameters(
        model=battery.model,
        fixed_level=FIXED_LEVEL.get(battery.model),
        resolution=show(battery.resolution_ah),
        capacity_ah=show(battery.capacity_ah),
        c_new=c_new,
        rc_max=battery.max_recharges,
        fade=fade,
        v_high=Ratio.of(thresholds.high, den),
        v_low=Ratio.of(thresholds.low, den),
        safe=Ratio.of(cfg.strategy.safe_t),
        costs=costs,
        cost_source=_cost_source(cfg),
        layout=layout,
        n_runs=runs(layout.n),
        dist_runs=runs(layout.dist),
        step_runs=runs(layout.step),
        p_wsp_c=cfg.environment.p_wsp_c,
        times={name: getattr(cfg.times_min, name) for name in type(cfg.times_min).model_fields},
    )
