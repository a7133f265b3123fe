"""PyBaMM runs (small): CSVs the other commands read, with the command line as a header."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from veribattery.cli import cli
from veribattery.phm.data import read_cycles, read_discharge

pytest.importorskip("pybamm", reason="the pybamm extra is not installed (make test installs it)")


def test_simulate_small_pack(tmp_path: Path) -> None:
    args = ["phm", "simulate", "--parameter-set", "Chen2020", "--power-w", "60",
            "--cells-series", "2", "--cells-parallel", "1", "--cycles", "3",
            "--period-s", "120", "-o", str(tmp_path)]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    discharge = (tmp_path / "discharge.csv").read_text().splitlines()
    assert discharge[0].startswith("# constant-power discharge")
    assert discharge[1].startswith("# veribattery") and "--power-w 60" in discharge[1]
    _, voltage, current = np.loadtxt(tmp_path / "discharge.csv", delimiter=",",
                                          comments="#", skiprows=3, unpack=True)
    # Constant power: pack voltage x current stays 60 W (2 cells of 30 W in series).
    assert voltage * current == pytest.approx(np.full_like(voltage, 60.0), rel=1e-3)
    assert voltage.min() >= 2 * 2.5 and voltage.max() <= 2 * 4.2 + 1e-6
    curve = read_discharge(tmp_path / "discharge.csv")
    assert curve.soc[0] == 1.0 and curve.soc[-1] == pytest.approx(0.0, abs=1e-9)
    log = read_cycles(tmp_path / "cycles.csv")
    assert log.cycle.tolist() == [1, 2, 3]
    # Chen2020 is a 5 Ah cell; SEI growth makes each discharge a little smaller.
    assert 4.0 < log.capacity_ah[0] < 5.1
    assert np.all(np.diff(log.capacity_ah) < 0)
    again = CliRunner().invoke(cli, args)
    assert again.exit_code == 2 and "already exist" in again.stderr


def test_unknown_parameter_set(tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["phm", "simulate", "--parameter-set", "Nope2000",
                                      "--power-w", "10", "-o", str(tmp_path)])
    assert result.exit_code == 2
    assert "unknown PyBaMM parameter set 'Nope2000'" in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_power_beyond_the_cell_is_one_line(tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["phm", "simulate", "--power-w", "2000",
                                      "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert "PyBaMM could not solve the experiment at 2000 W per cell" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("args", "expected"), [
    (["--power-w", "nan"], "--power-w: must be a number of watts > 0, got nan"),
    (["--power-w", "inf"], "--power-w: must be a number of watts > 0, got inf"),
    (["--power-w", "10", "--period-s", "nan"], "--period-s: must be a number of seconds >= 1"),
    (["--power-w", "10", "--period-s", "inf"], "--period-s: must be a number of seconds >= 1"),
    # PyBaMM reads '1e+308 W' as '1e' watts: a ValueError traceback; now it is solved
    (["--power-w", "1e308"], "PyBaMM could not solve the experiment at 1e+308 W per cell"),
    # 24 h at 0.1 W leaves the cell at 4.09 V: a partial discharge was written as if whole
    (["--power-w", "0.1"], "--power-w 0.1: after 86400 s the cells are still at 4.09 V, "
                           "above their 2.5 V cut-off: not a whole discharge"),
], ids=["nan", "inf", "period-nan", "period-inf", "1e308", "too-low"])
def test_powers_and_periods_pybamm_cannot_use(tmp_path: Path, args: list[str],
                                              expected: str) -> None:
    result = CliRunner().invoke(cli, ["phm", "simulate", *args, "-o", str(tmp_path / "out")])
    assert result.exit_code == 2, (result.output, result.exception)
    assert result.stderr.startswith(f"error: {expected}"), result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()
