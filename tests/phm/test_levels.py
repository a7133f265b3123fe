"""Step approximation (BA3): thresholds minimise the error (vs brute force); Eq. 2 table."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from tests.phm.helpers import write_csv
from veribattery.config import consumption_units, load_config
from veribattery.phm.data import DischargeCurve, read_discharge
from veribattery.phm.levels import fit_steps, fixed_steps, resample, step_error
from veribattery.phm.recheck import flatten
from veribattery.phm.refit import level_parameters


def _curve(soc: np.ndarray, voltage: np.ndarray) -> DischargeCurve:
    return DischargeCurve(soc[::-1].copy(), voltage[::-1].copy(), None, "test.csv")


def _brute_force(voltage: np.ndarray) -> tuple[int, int, float]:
    best = (0, 0, np.inf)
    for i in range(1, len(voltage) - 1):
        for j in range(i, len(voltage) - 1):
            _, sse = step_error(voltage, i, j)
            if sse < best[2]:
                best = (i, j, sse)
    return best


@pytest.mark.parametrize("seed", range(5))
def test_thresholds_match_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    soc = np.linspace(0, 1, 41)
    voltage = 20 + 5 * soc + 1.5 * np.tanh((soc - 0.1) * 20) + rng.normal(0, 0.05, soc.size)
    voltage = np.maximum.accumulate(voltage)  # a discharge curve falls as SOC falls
    fit = fit_steps(_curve(soc, voltage), Fraction(1, 40))
    i, j, sse = _brute_force(np.interp(np.linspace(0, 1, 41), soc, voltage))
    assert (fit.low, fit.high) == (Fraction(i, 40), Fraction(j, 40))
    assert fit.rms_v == pytest.approx(np.sqrt(sse / 41), rel=1e-9)


def test_exact_steps_recovered() -> None:
    soc = np.arange(101) / 100  # exact 0.7, unlike linspace
    voltage = np.where(soc > 0.7, 25.0, np.where(soc < 0.2, 20.0, 22.0))
    fit = fit_steps(_curve(soc, voltage))
    assert (fit.low, fit.high) == (Fraction(1, 5), Fraction(7, 10))
    assert fit.voltages == pytest.approx((20.0, 22.0, 25.0))
    assert fit.rms_v == pytest.approx(0.0, abs=1e-12) and fit.max_v == pytest.approx(0.0)


def test_fixed_thresholds_never_beat_the_optimum() -> None:
    soc = np.linspace(0, 1, 201)
    voltage = 19 + 6 * soc**0.5
    curve = _curve(soc, voltage)
    best, paper = fit_steps(curve), fixed_steps(curve, Fraction(1, 4), Fraction(3, 4))
    assert best.rms_v <= paper.rms_v
    # The paper's levels on its thresholds are the segment means, by hand.
    grid = np.linspace(0, 1, 101)
    expected_low = np.mean(19 + 6 * grid[grid < 0.25] ** 0.5)
    assert paper.voltages[0] == pytest.approx(expected_low, rel=1e-4)


def test_resample_partial_range() -> None:
    soc = np.array([0.95, 0.5, 0.05])
    soc_grid, voltage, first = resample(_curve(soc[::-1], np.array([20.0, 22.0, 25.0])),
                                        Fraction(1, 10))
    assert first == 1 and soc_grid[0] == pytest.approx(0.1) and soc_grid[-1] == pytest.approx(0.9)
    assert voltage[4] == pytest.approx(22.0)


def test_eq2_table_matches_config_layer(tmp_path: Path) -> None:
    """The phm table for the fitted voltages equals the config layer's, once merged."""
    soc = np.linspace(0, 1, 101)
    voltage = np.where(soc > 0.75, 25.0, np.where(soc < 0.25, 20.0, 22.0)) + 0.3 * soc
    path = write_csv(tmp_path / "d.csv", "soc,voltage_v", zip(soc[::-1], voltage[::-1],
                                                             strict=True))
    for resolution in ("0.1", "0.05"):
        cfg = load_config(f"battery:\n  resolution_ah: {resolution}\n  capacity_ah: 11\n")
        params = level_parameters(read_discharge(path), cfg)
        merged = load_config(f"battery:\n  resolution_ah: {resolution}\n  capacity_ah: 11\n",
                             params.fragment.overrides())
        units = consumption_units(merged.battery)
        for action, table in params.table.items():
            assert units.of(action) == table
        flat = flatten(params.fragment.values)
        assert flat["battery.consumption.voltages_v.low"] == params.voltages_v[0]


def test_paper_voltages_give_paper_table() -> None:
    """With the paper's 20/22/25 V, Eq. 2 must give Table 2 (0.1 Ah units, low wind)."""
    from veribattery.phm.levels import eq2_table
    from veribattery.phm.refit import eq2_inputs

    table = eq2_table(eq2_inputs(load_config("")), (Fraction(20), Fraction(22), Fraction(25)),
                      Fraction(1, 10))
    assert table["inspection"][0] == (45, 41, 36)  # 180*0.25/(V*0.5)/0.1: 45, 40.9, 36
    assert table["takeoff_land"][0] == (3, 3, 2)
