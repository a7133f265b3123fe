"""Fade fits on synthetic data with known parameters: recovery, AIC choice, CI coverage."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from tests.phm.helpers import EXAMPLES, cycles_csv, knee_curve
from veribattery.config import load_config
from veribattery.phm.data import PhmDataError, read_cycles
from veribattery.phm.fade import FadeFit, _aic, fit_all, fit_exponential, fit_knee, fit_linear
from veribattery.phm.refit import BeyondDataError, fade_parameters

RNG_SEED = 20190101


def _log(tmp_path: Path, cycles: np.ndarray, capacity: np.ndarray, noise: float = 0.0,
         seed: int = RNG_SEED) -> object:
    rng = np.random.default_rng(seed)
    noisy = capacity + rng.normal(0.0, noise, size=capacity.shape)
    return read_cycles(cycles_csv(tmp_path / "cycles.csv", cycles, noisy))


def test_linear_recovered(tmp_path: Path) -> None:
    n = np.arange(0, 401, 10.0)
    log = _log(tmp_path, n, 11.0 - 0.02 * n, noise=0.02)
    fit = fit_linear(log)  # type: ignore[arg-type]
    assert fit.params["a"] == pytest.approx(11.0, abs=0.03)
    assert fit.params["b"] == pytest.approx(0.02, rel=0.02)
    # Relative fade at cycle N is b / (a - b N), by hand.
    assert fit.relative_fade(400) == pytest.approx(0.02 / (11.0 - 8.0), rel=0.03)
    assert fit.loss_per_cycle(123.0) == pytest.approx(fit.params["b"], rel=1e-6)


def test_exponential_recovered_and_chosen(tmp_path: Path) -> None:
    n = np.arange(0, 301, 5.0)
    log = _log(tmp_path, n, 11.0 * np.exp(-0.004 * n), noise=0.01)
    report = fit_all(log)  # type: ignore[arg-type]
    assert report.chosen.name == "exponential"
    fit = report.chosen
    assert fit.params["a"] == pytest.approx(11.0, abs=0.02)
    assert fit.params["k"] == pytest.approx(0.004, rel=0.01)
    assert fit.relative_fade(150) == pytest.approx(fit.params["k"], rel=1e-6)
    assert "exponential has the lowest AIC" in report.explanation()
    linear = next(f for f in report.fits if f.name == "linear")
    assert linear.aic - fit.aic > 10  # decisive, not a coin toss


def test_linear_chosen_over_curved_models(tmp_path: Path) -> None:
    n = np.arange(0, 401, 10.0)
    log = _log(tmp_path, n, 11.0 - 0.02 * n, noise=0.02)
    report = fit_all(log)  # type: ignore[arg-type]
    exponential = next(f for f in report.fits if f.name == "exponential")
    linear = next(f for f in report.fits if f.name == "linear")
    assert linear.aic < exponential.aic - 10


def test_knee_recovered_and_chosen(tmp_path: Path) -> None:
    n = np.arange(0, 401, 5.0)
    log = _log(tmp_path, n, knee_curve(n, 11.0, 0.002, 0.02, 250.0), noise=0.01)
    report = fit_all(log)  # type: ignore[arg-type]
    assert report.chosen.name == "knee"
    params = report.chosen.params
    assert params["nk"] == pytest.approx(250.0, abs=5.0)
    assert params["b1"] == pytest.approx(0.002, rel=0.1)
    assert params["b2"] == pytest.approx(0.02, rel=0.03)
    # After the knee the loss per cycle is b2.
    assert report.chosen.loss_per_cycle(380.0) == pytest.approx(params["b2"], rel=1e-6)


def test_knee_needs_six_points(tmp_path: Path) -> None:
    n = np.array([0.0, 10.0, 20.0, 30.0, 40.0])
    report = fit_all(_log(tmp_path, n, 11.0 - 0.01 * n, noise=0.001))  # type: ignore[arg-type]
    assert "knee" in report.skipped
    assert {f.name for f in report.fits} == {"linear", "exponential"}


def test_fade_ci_covers_truth_about_95_percent(tmp_path: Path) -> None:
    """Frequentist sanity of the delta-method interval: ~95% of intervals hold the truth."""
    n = np.arange(0, 101, 5.0)
    truth = 0.01 / (11.0 - 0.01 * 100)
    hits = 0
    trials = 200
    for seed in range(trials):
        log = _log(tmp_path, n, 11.0 - 0.01 * n, noise=0.05, seed=seed)
        low, high = fit_linear(log).fade_interval(100.0)  # type: ignore[arg-type]
        hits += low <= truth <= high
    assert 0.90 <= hits / trials <= 0.99


def test_exact_exponential_has_zero_width_ci(tmp_path: Path) -> None:
    n = np.arange(0, 101, 10.0)
    fit = fit_exponential(_log(tmp_path, n, 2.0 * np.exp(-0.003 * n)))  # type: ignore[arg-type]
    low, high = fit.fade_interval(50.0)
    assert low == pytest.approx(0.003, rel=1e-6) and high == pytest.approx(0.003, rel=1e-6)


def test_parameters_on_config_grid(tmp_path: Path) -> None:
    n = np.arange(0, 201, 10.0)
    log = _log(tmp_path, n, 11.0 * np.exp(-0.002 * n))
    cfg = load_config("battery:\n  resolution_ah: 0.1\n")
    params = fade_parameters(log, cfg)  # type: ignore[arg-type]
    expected = 11.0 * np.exp(-0.4)  # 7.3735...
    assert params.capacity_fit_ah == pytest.approx(expected, rel=1e-6)
    assert params.capacity_ah == Fraction(74, 10)
    assert params.fade_per_recharge == Fraction(2, 1000)
    assert params.fragment.yaml() == (
        "battery:\n  capacity_ah: 7.4\n  fade_per_recharge: 0.002\n")
    at_50 = fade_parameters(log, cfg, at_cycle=50)  # type: ignore[arg-type]
    assert at_50.capacity_ah == Fraction(10)  # 11 e^-0.1 = 9.953 -> 10.0 (nearest 0.1)


@pytest.mark.parametrize("cycle", [-5.0, float("nan"), float("inf")])
def test_at_cycle_must_be_a_cycle(tmp_path: Path, cycle: float) -> None:
    n = np.arange(0, 101, 10.0)
    log = _log(tmp_path, n, 11.0 - 0.001 * n)
    with pytest.raises(PhmDataError, match=r"at_cycle must be a cycle number >= 0, got"):
        fade_parameters(log, load_config(""), at_cycle=cycle)  # type: ignore[arg-type]


def test_fit_with_capacity_rising_at_cycle_is_refused(tmp_path: Path) -> None:
    n = np.arange(0, 101, 10.0)
    capacity = knee_curve(n, 11.0, 0.02, -0.005, 60.0)  # falls, then rises a little
    log = _log(tmp_path, n, capacity)
    cfg = load_config("")
    with pytest.raises(PhmDataError, match=r"cycles.csv:\d+: row \d+, column 'capacity_ah': "
                                           r"the knee fit has the capacity rising"):
        fade_parameters(log, cfg, model="knee")  # type: ignore[arg-type]


def test_knee_fit_direct(tmp_path: Path) -> None:
    n = np.arange(0, 101, 4.0)
    fit = fit_knee(_log(tmp_path, n, knee_curve(n, 5.0, 0.001, 0.01, 50.0)))  # type: ignore[arg-type]
    # Between logged cycles (48, 52) the knee is where the two phases' lines cross: exact.
    assert fit.params["nk"] == pytest.approx(50.0, rel=1e-9)
    assert fit.rmse < 1e-9


def test_knee_on_a_logged_cycle_is_found_exactly() -> None:
    """The example's least squares have a kink at the knee, cycle 18: curve_fit stopped at
    18.01 (or 17.98, 18.0015, ... by start), and the interval's 4th digit with it."""
    log = read_cycles(EXAMPLES / "cycles.csv")
    fit = fit_knee(log)
    assert fit.params["nk"] == 18.0
    sse = float(fit.residuals @ fit.residuals)
    for nk in (17.9999, 18.0001, 17.5, 19.05):  # 19.05: the next-best local minimum
        moved = knee_curve(log.cycle, *_relinear(log.cycle, log.capacity_ah, nk), nk)
        assert sse < float(np.sum((log.capacity_ah - moved) ** 2))
    low, high = fit.fade_interval(30.0)
    assert (f"{low:.4g}", f"{high:.4g}") == ("0.0001447", "0.0001453")


def _relinear(n: np.ndarray, y: np.ndarray, nk: float) -> tuple[float, float, float]:
    """The best a, b1, b2 for a knee at *nk* (they are linear)."""
    design = np.column_stack([np.ones_like(n), -np.minimum(n, nk), -np.maximum(n - nk, 0.0)])
    a, b1, b2 = np.linalg.lstsq(design, y, rcond=None)[0]
    return float(a), float(b1), float(b2)


def test_extrapolation_to_no_capacity_is_refused(tmp_path: Path) -> None:
    n = np.arange(0, 101, 10.0)
    log = _log(tmp_path, n, 11.0 - 0.05 * n)  # linear: zero at cycle 220
    with pytest.raises(PhmDataError, match=r"cycles.csv:12: row 11, column 'capacity_ah': the "
                                           r"linear fit gives capacity -4 Ah at cycle 300"):
        fade_parameters(log, load_config(""), at_cycle=300, model="linear")  # type: ignore[arg-type]


def test_flat_noisy_log_gives_zero_fade(tmp_path: Path) -> None:
    """No measurable fade: a slope whose CI includes zero is read as no fade, not a rise."""
    n = np.arange(0, 101, 10.0)
    clamped = 0
    for seed in range(20):
        try:
            log = _log(tmp_path, n, np.full(n.shape, 11.0), noise=0.01, seed=seed)
        except PhmDataError:
            continue  # ends above its start: refused by the reader as "increases overall"
        params = fade_parameters(log, load_config(""), model="linear")  # type: ignore[arg-type]
        raw = params.fit.relative_fade(100.0)
        if raw < 0:
            assert params.fade_ci[1] >= 0 and params.fade == 0
            clamped += 1
        assert params.fade_per_recharge >= 0 and params.capacity_ah == 11
    assert clamped > 0, "some seed should give an insignificant rising slope"



def test_aic_of_residuals_near_the_largest_double_is_finite() -> None:
    """Residuals and scale times 10^300 shift the AIC by n ln(10^600) only (the mean square
    scaled back overflowed: every fit's AIC was inf, the penalty 2k lost)."""
    residuals = np.array([0.01, -0.02, 0.003, 0.015])
    shift = residuals.size * 600 * np.log(10.0)
    for k in (2, 3):
        small, large = _aic(residuals, k, 11.0), _aic(residuals * 1e300, k, 11.0e300)
        assert large - shift == pytest.approx(small, abs=1e-9)


def test_aic_of_capacities_near_the_smallest_double_is_finite() -> None:
    """The floor was log(1e-12 x scale): below 1e-296 Ah that is log(0), and every fit was
    skipped as "did not converge (math domain error)"."""
    residuals = np.array([0.1, -0.2, 0.03, 0.15])
    shift = residuals.size * 2 * np.log(1e-316)  # (doubles this small keep 7 digits)
    assert _aic(residuals * 1e-316, 2, 4e-316) - shift == pytest.approx(
        _aic(residuals, 2, 4.0), abs=1e-3)


def test_relative_fade_where_the_fit_underflows_to_zero_is_nan() -> None:
    """An exponential read far out is 0 Ah: its relative fade was a ZeroDivisionError
    (a traceback in phm fade); it is NaN, which fade_parameters refuses with a location."""
    fit = FadeFit("exponential", "", {"a": 11.0, "k": 0.01}, np.zeros((2, 2)),
                  np.zeros(4), 0.0)
    assert fit.relative_fade(100.0) == pytest.approx(0.01)
    assert np.isnan(fit.relative_fade(1e6))


def test_exponential_refuses_capacities_without_a_logarithm(tmp_path: Path) -> None:
    log = read_cycles(cycles_csv(tmp_path / "c.csv", np.arange(4.0), np.arange(4.0, 0, -1)))
    table = log.table
    table.columns["capacity_ah"][-1] = 0.0  # past the reader's check: the API takes any log
    with pytest.raises(ValueError, match="needs capacities > 0"):
        fit_exponential(log)


def test_a_cycle_too_far_ahead_says_how_far_the_fit_reaches() -> None:
    """Past the log, a failing cycle is the caller's choice, not the data's fault: the
    error says so and how far the fit does reach (the last logged row was blamed)."""
    log, cfg = read_cycles(EXAMPLES / "cycles.csv"), load_config("")
    with pytest.raises(BeyondDataError) as caught:
        fade_parameters(log, cfg, at_cycle=1e9)
    exc = caught.value
    assert (exc.cycle, exc.last) == (1e9, 30.0)
    assert exc.reason.startswith("the knee fit gives capacity -1.379e+06 Ah at cycle 1e+09")
    assert str(exc).startswith("cycle 1e+09 is too far beyond the log's last cycle 30: ")
    assert str(exc).endswith(f"; the fit is usable up to cycle {30 + exc.ahead}")
    fade_parameters(log, cfg, at_cycle=exc.last + exc.ahead)  # the reach is real ...
    with pytest.raises(BeyondDataError):
        fade_parameters(log, cfg, at_cycle=exc.last + exc.ahead + 1)  # ... and the most


def test_a_fade_beyond_floating_point_is_refused(tmp_path: Path) -> None:
    """Cycles numbered from 1e15: the exponential's fade interval overflowed to (nan, nan),
    with numpy's warnings printed; now a located error."""
    n = 1e15 + np.arange(4.0)
    log = read_cycles(cycles_csv(tmp_path / "c.csv", n, 10.0 - 0.1 * np.arange(4.0)))
    with pytest.raises(PhmDataError, match=r"c\.csv:5: row 4, column 'capacity_ah': the "
                                           r"exponential fit's fade at cycle 1e\+15 is beyond"):
        fade_parameters(log, load_config(""), model="exponential")
