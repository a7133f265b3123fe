"""The battery's voltage levels and BS1's rule as a charge threshold, state by state,
against the spec read independently (tests/render/spec_mdp.py for the level, exact
fractions for ``ok_X``)."""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest

from tests.render.spec_mdp import SpecMission, State
from veribattery.config import MissionConfig, derive_parameters, load_config
from veribattery.synthesis.bs1_rule import bs1_least_go_on, bs1_least_go_on_at
from veribattery.synthesis.decisions import DECISIONS
from veribattery.synthesis.levels import capacities, level_bands, voltage_levels

SMALL = ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=6",
         "battery.max_recharges=8", "environment.p_wsp_c=0.3")
#: Variants: the voltage levels and fade, a fixed level, odd thresholds and a steep
#: fade (cap falls fast), another safe_t, a route with longer distances.
CONFIGS = {
    "small": SMALL,
    "basic-low": (*SMALL, "battery.model=basic_low", "strategy.safe_t=0.1"),
    "odd-thresholds": (*SMALL, "battery.voltage_thresholds={high: 2/3, low: 1/3}",
                       "battery.fade_per_recharge=0.03", "strategy.safe_t=1/7"),
    "three-by-three": ("farm.cols=3", "farm.rows=3", "farm.base=[1,1]",
                       "battery.capacity_ah=8", "battery.max_recharges=12",
                       "strategy.safe_t=0.2"),
    "columns-eq2": ("farm.cols=4", "farm.rows=2", "farm.base=[1,0]",
                    "farm.route=snake_columns", "battery.capacity_ah=6",
                    "battery.max_recharges=6", "battery.consumption={energy_wh: 180}"),
}


def _cfg(name: str) -> MissionConfig:
    return load_config("", CONFIGS[name])


def _every_charge(spec: SpecMission) -> tuple[np.ndarray, np.ndarray]:
    """(b, rc) for every charge 0..cap(rc) and every recharge count."""
    pairs = [(b, rc) for rc in range(spec.rc_max + 1) for b in range(spec.cap(rc) + 1)]
    return np.array([b for b, _ in pairs]), np.array([rc for _, rc in pairs])


@pytest.mark.parametrize("name", list(CONFIGS))
def test_levels_are_the_specs(name: str) -> None:
    cfg = _cfg(name)
    spec, params = SpecMission.of(cfg), derive_parameters(cfg)
    b, rc = _every_charge(spec)
    assert list(capacities(params, np.arange(spec.rc_max + 1))) == [
        spec.cap(r) for r in range(spec.rc_max + 1)]
    assert list(voltage_levels(params, b, rc)) == [
        spec.level(x, r) for x, r in zip(b.tolist(), rc.tolist(), strict=True)]


@pytest.mark.parametrize("name", list(CONFIGS))
def test_level_bands_hold_exactly_their_levels_charges(name: str) -> None:
    cfg = _cfg(name)
    spec, params = SpecMission.of(cfg), derive_parameters(cfg)
    for rc in range(spec.rc_max + 1):
        least, greatest = level_bands(params, np.arange(3), np.full(3, rc))
        for level in range(3):
            band = set(range(int(least[level]), int(greatest[level]) + 1))
            assert band == {b for b in range(spec.cap(rc) + 1) if spec.level(b, rc) == level}


def _ok(spec: SpecMission, safe_t: Fraction, decision: str, x: State) -> bool:
    """The spec's ok_X at x, in exact fractions: b - pred >= safe_t x cap(rc)."""
    tl, cell, ins = spec.costs(x)
    pred = {"takeoff": tl + spec.dist[x.k] * cell + ins, "fly": spec.dist[x.k] * cell + ins,
            "inspect": ins,
            "next": (spec.step[x.k] if x.k < spec.K - 1 else 0) * cell + ins}[decision]
    return x.b - pred >= safe_t * spec.cap(x.rc)


@pytest.mark.parametrize("name", list(CONFIGS))
def test_bs1_goes_on_exactly_from_its_threshold(name: str) -> None:
    """For every decision, cell, wind, recharge count and charge: BS1's ok_X holds iff
    the charge is at least the rule's threshold at its level; and ok_X is monotone in
    the charge (a threshold across the levels too)."""
    cfg = _cfg(name)
    spec, params = SpecMission.of(cfg), derive_parameters(cfg)
    b, rc = _every_charge(spec)
    levels = voltage_levels(params, b, rc)
    mixed = 0
    for decision, k, wsp in itertools.product(DECISIONS, range(spec.K), (0, 1)):
        least = bs1_least_go_on_at(params, np.full(b.shape, decision, dtype=object),
                                   np.full(b.shape, k), np.full(b.shape, wsp), rc, levels)
        ok = np.array([_ok(spec, cfg.strategy.safe_t, decision, State(0, k, 0, x, r, wsp))
                       for x, r in zip(b.tolist(), rc.tolist(), strict=True)])
        assert ok.tolist() == ((least >= 0) & (b >= least)).tolist()
        for r in range(spec.rc_max + 1):
            run = ok[rc == r].tolist()
            assert run == sorted(run)  # False ... False True ... True
            mixed += (True in run) and (False in run)
    assert mixed > 0


def test_bs1_threshold_by_hand() -> None:
    """SMALL (C_NEW 60, safe_t 0.3: a reserve of 18 units), inspecting cell k=1 in low
    wind before any recharge: 36 units at high voltage, so from 36 + 18 = 54 on (the high
    band is 46..60); at medium voltage 40 + 18 = 58 lies above the band (15..45): never.
    Taking off at k=1 in low wind and high voltage: 1 + 1 x 3 + 36 + 18 = 58."""
    params = derive_parameters(_cfg("small"))
    assert bs1_least_go_on(params, "inspect", 1, 0, 0, 2) == 54
    assert bs1_least_go_on(params, "inspect", 1, 0, 0, 1) is None
    assert bs1_least_go_on(params, "takeoff", 1, 0, 0, 2) == 58
    # After 8 recharges cap is 59: the reserve is ceil(17.7) = 18 still; high band 45..59.
    assert bs1_least_go_on(params, "inspect", 1, 0, 8, 2) == 54
