"""The integers of the generated model stay within PRISM's 32-bit ``int``.

The model compares charge on integers (decisions.md, 5): ``C_NEW``, the costs in
units, and the guards of BS1 and of the voltage levels, which multiply the charge by
the denominator of ``safe_t`` or of the thresholds. A config whose numbers would make
these products overflow PRISM's ints (a ``safe_t`` of ``1e-30`` is a denominator of
10^30) is refused here, naming the key, before any model is rendered: PRISM would
compute wrong guards, and even veribattery's 64-bit ints cannot hold such literals.
"""

from __future__ import annotations

import math
from decimal import Decimal
from fractions import Fraction

from veribattery.config.battery import ACTIONS, CostTable
from veribattery.config.exact import brief, fraction_to_decimal
from veribattery.config.farm import FarmLayout
from veribattery.config.schema import ConsumptionTable, MissionConfig
from veribattery.errors import ConfigError

__all__ = ["PRISM_INT_MAX", "check_int_ranges"]

#: PRISM's integers are Java ``int``: intermediate products must stay below this.
PRISM_INT_MAX = 2**31 - 1
#: Bound of a single quantity of charge (C_NEW, the most a decision predicts), so that
#: their sums and differences stay below PRISM_INT_MAX.
_CHARGE_MAX = PRISM_INT_MAX // 2
_LEVELS = ("low", "medium", "high")


def check_int_ranges(cfg: MissionConfig, c_new: int, costs: CostTable,
                     layout: FarmLayout) -> None:
    """Refuse a config whose numbers overflow the model's integers (see the module).

    :raises ConfigError: naming the key to change (the one the user gave, of the keys
        whose change would do), placed where it was given, and what it must stay below.
    """
    _check_fade(cfg, c_new)
    if cfg.battery.max_recharges >= PRISM_INT_MAX:
        raise cfg.key_error(("battery.max_recharges", "must be below 2^31 - 1 for PRISM's "
                             f"32-bit integers, got {brief(cfg.battery.max_recharges)}"))
    reach = max((*layout.dist, *layout.step), default=0)
    predicted = _check_costs(cfg, costs, reach)
    _check_constants(cfg, costs)
    _check_guards(cfg, c_new, predicted)
    _check_times(cfg, reach)
    _check_ratio(cfg, "environment.p_wsp_c", cfg.environment.p_wsp_c)


def _check_costs(cfg: MissionConfig, costs: CostTable, reach: int) -> int:
    """The most charge a decision predicts, which must stay below 2^30."""
    predicted = max(_most_predicted(costs, reach, wind) for wind in (0, 1))
    if predicted <= _CHARGE_MAX:
        return predicted
    raise _cost_error(cfg, _cost_key(cfg, costs, reach),
                      f"a take-off, the flight to the farthest cell ({reach} cells) and an "
                      f"inspection would need {_digits(predicted)} units of resolution_ah "
                      f"({brief(cfg.battery.resolution_ah)}), which must stay below 2^30 for "
                      "PRISM's 32-bit integers")


def _check_constants(cfg: MissionConfig, costs: CostTable) -> None:
    """Every cost is an int constant of the model, used or not: on a farm whose decisions
    fly no cell (one cell), the predictions of :func:`_check_costs` leave ``cell`` out."""
    most = max(max(max(levels) for levels in costs.of(a)) for a in ACTIONS)
    if most <= _CHARGE_MAX:
        return
    raise _cost_error(cfg, _cost_key(cfg, costs, 1),
                      f"one action would cost {_digits(most)} units of resolution_ah "
                      f"({brief(cfg.battery.resolution_ah)}), an int constant of the model, "
                      "which must stay below 2^30 for PRISM's 32-bit integers")


def _cost_error(cfg: MissionConfig, given: tuple[str, Fraction | None],
                need: str) -> ConfigError:
    """Charge beyond PRISM's ints: the consumption key *given* (and its value) is too
    large, or ``resolution_ah`` too fine, whichever the user gave; *need* says why."""
    key, value = given
    return cfg.key_error(
        (key, f"{'' if value is None else brief(value) + ' is '}too large: {need}"),
        ("battery.resolution_ah", f"{brief(cfg.battery.resolution_ah)} is too fine: {need}"))


def _check_guards(cfg: MissionConfig, c_new: int, predicted: int) -> None:
    """BS1's guards (``den*(b - pred) >= num*cap``) and the voltage levels'."""
    if cfg.strategy.mode == "bs1":
        safe_t = cfg.strategy.safe_t
        _check_fine(cfg, ("strategy.safe_t", safe_t), safe_t.denominator, c_new + predicted,
                    "BS1's guards multiply the charge", "safe_t's denominator")
    if cfg.battery.model == "advanced":
        levels = cfg.battery.voltage_thresholds
        finer = max(("high", "low"), key=lambda k: getattr(levels, k).denominator)
        common = math.lcm(levels.high.denominator, levels.low.denominator)
        _check_fine(cfg, (f"battery.voltage_thresholds.{finer}", getattr(levels, finer)),
                    common, c_new, "the voltage guards multiply the charge",
                    "the thresholds' common denominator")


def _check_fade(cfg: MissionConfig, c_new: int) -> None:
    """``cap`` multiplies C_NEW by the fade's denominator."""
    den = cfg.battery.fade.denominator
    if c_new * den > _CHARGE_MAX:
        message = ("capacity_ah/resolution_ah x the fade's denominator "
                   f"({_digits(c_new)} x {_digits(den)}) must stay below 2^30 for PRISM's "
                   "32-bit integers")
        raise cfg.key_error(*((f"battery.{key}", message) for key in
                              ("fade_per_recharge", "capacity_ah", "resolution_ah")))


def _most_predicted(costs: CostTable, reach: int, wind: int) -> int:
    """An upper bound of the charge one decision predicts in *wind*: a take-off, the
    flight across *reach* cells and an inspection."""
    most = {a: max(costs.of(a)[wind]) for a in ACTIONS}
    return most["takeoff_land"] + reach * most["cell"] + most["inspection"]


def _cost_key(cfg: MissionConfig, costs: CostTable, reach: int) -> tuple[str, Fraction | None]:
    """The consumption key that makes the prediction too large, and its value: the
    table's entry that weighs most at low wind, its high-wind factor if low wind alone
    fits, or the section (no value) for Eq. 2's parameters."""
    table = cfg.battery.consumption
    if not isinstance(table, ConsumptionTable):
        return "battery.consumption", None
    if _most_predicted(costs, reach, 0) <= _CHARGE_MAX:
        return "battery.consumption.high_wind_factor", table.high_wind_factor
    weight = {"takeoff_land": 1, "cell": max(reach, 1), "inspection": 1}
    _, action, level = max((costs.of(a)[0][i] * weight[a], a, i)
                           for a in ACTIONS for i in range(3))
    key = f"{action}.{_LEVELS[level]}"
    return f"battery.consumption.{key}", getattr(getattr(table, action), _LEVELS[level])


def _check_fine(cfg: MissionConfig, given: tuple[str, Fraction], den: int, charge: int,
                guards: str, den_name: str) -> None:
    """Guards ``den*charge > num*cap``: *den* times *charge* must stay below 2^31."""
    if den * charge <= PRISM_INT_MAX:
        return
    key, value = given
    limit = PRISM_INT_MAX // charge
    raise cfg.key_error((key,
        f"{brief(value)} is too fine: {guards} (up to {charge} units) by {den_name} "
        f"({_digits(den)}), and PRISM's 32-bit integers hold products below 2^31; give a "
        f"denominator of at most {limit} (e.g. at most {len(str(limit)) - 1} decimal places)"))


def _check_times(cfg: MissionConfig, reach: int) -> None:
    """A whole number of minutes is an int constant (``T_CELL`` is multiplied by a
    distance in cells)."""
    for name, value in cfg.times_min:
        key = f"times_min.{name}"
        most = PRISM_INT_MAX // max(reach, 1) if name == "per_cell" else PRISM_INT_MAX
        if value > most:
            scaled = " x the longest flight in cells" if name == "per_cell" else ""
            raise cfg.key_error((key, f"{brief(value)} is too large: minutes{scaled} must "
                                 f"stay at most {most} for PRISM's 32-bit integers"))
        _check_ratio(cfg, key, value)


def _check_ratio(cfg: MissionConfig, key: str, value: Fraction) -> None:
    """A value that is no decimal is written ``(p/q)``: q must be an int too."""
    if fraction_to_decimal(value) is None and value.denominator > PRISM_INT_MAX:
        raise cfg.key_error((key, f"{brief(value)} has a denominator too large for PRISM's "
                             f"32-bit integers: give a decimal, or p/q with q at most "
                             f"{PRISM_INT_MAX}"))


def _digits(value: int) -> str:
    """*value*, or 10^n for a long power of ten, or about so much (never ``str`` of an
    int of thousands of digits, which Python refuses)."""
    if value < 10**20:
        return str(value)
    power = Decimal(value).adjusted()
    if value == 10**power:
        return f"10^{power}"
    return f"about {Decimal(value).normalize():.3g}"
