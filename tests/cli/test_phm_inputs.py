"""Bad input to the phm commands: one ``error:`` line, exit 2, no traceback, no file written,
and all of it before any work starts; user text is printed as typed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result

from tests.phm.helpers import EXAMPLES, cycles_csv
from veribattery.cli import cli

SMALL = ("--set", "farm.cols=3", "--set", "farm.rows=3", "--set", "farm.base=[0,0]")
PNG = b"\x89PNG\r\n\x1a\n"


def run(*args: str) -> Result:
    return CliRunner().invoke(cli, list(args))


def files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def assert_one_error(result: Result, *parts: str) -> str:
    """Exit 2, stderr exactly one ``error:`` line holding *parts*, nothing on stdout."""
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    for part in parts:
        assert part in lines[0]
    assert result.stdout == ""
    return lines[0]


@pytest.fixture
def mission(tmp_path: Path) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text("battery:\n  capacity_ah: 11\n  max_recharges: 50\n")
    return path


def _command(name: str, tmp_path: Path, mission: Path) -> list[str]:
    if name == "fade":
        return ["phm", "fade", str(EXAMPLES / "cycles.csv")]
    if name == "levels":
        return ["phm", "levels", str(EXAMPLES / "discharge.csv")]
    return ["phm", "forecast", str(mission), "--cycles", str(EXAMPLES / "cycles.csv"),
            "--horizon", "10", *SMALL]


@pytest.mark.parametrize("command", ["fade", "levels", "forecast"])
@pytest.mark.parametrize(("name", "kind"), [("x.xyz", "'.xyz'"), ("figure", "no file type")])
def test_plot_type_checked_before_work(tmp_path: Path, mission: Path, command: str, name: str,
                                       kind: str) -> None:
    before = files(tmp_path)
    result = run(*_command(command, tmp_path, mission), "--plot", str(tmp_path / name))
    assert_one_error(result, f"--plot {tmp_path / name}: ", kind, "name a file ending in .png")
    assert files(tmp_path) == before


@pytest.mark.parametrize("command", ["fade", "levels"])
def test_plot_overwrites_only_with_force(tmp_path: Path, mission: Path, command: str) -> None:
    png = tmp_path / "mine.png"
    png.write_bytes(b"keep")
    result = run(*_command(command, tmp_path, mission), "--plot", str(png))
    assert_one_error(result, f"--plot {png}: already exists; use --force")
    assert png.read_bytes() == b"keep"
    result = run(*_command(command, tmp_path, mission), "--plot", str(png), "--force")
    assert result.exit_code == 0, result.output
    assert png.read_bytes().startswith(PNG)


def test_plot_in_a_missing_folder(tmp_path: Path) -> None:
    result = run("phm", "fade", str(EXAMPLES / "cycles.csv"), "--plot",
                 str(tmp_path / "nowhere" / "f.png"))
    assert_one_error(result, "folder", "does not exist")


def test_forecast_unknown_time_property(tmp_path: Path, mission: Path) -> None:
    result = run(*_command("forecast", tmp_path, mission), "--time-property", "nosuch")
    line = assert_one_error(result, "--time-property nosuch:", "'nosuch'", "p_success",
                            "exp_mission_time")
    assert str(mission) in line


def test_forecast_unknown_requirement_property(tmp_path: Path, mission: Path) -> None:
    result = run(*_command("forecast", tmp_path, mission), "--require", "p_nope >= 0.9")
    assert_one_error(result, "--require", "'p_nope'", "p_success")


def test_forecast_probability_bound_outside_0_1(tmp_path: Path, mission: Path) -> None:
    """It printed "p_success >= 2 already fails now" and exited 0: a bound no probability
    can meet is bad input, as in a config's requirements."""
    result = run(*_command("forecast", tmp_path, mission), "--require", "p_success >= 2")
    line = assert_one_error(result)
    assert line == ('error: --require p_success >= 2: p_success is a probability '
                    '(P=? [ F "success" ]): the bound must be in [0, 1], got 2')


def test_forecast_empty_time_property_means_none(tmp_path: Path, mission: Path) -> None:
    result = run(*_command("forecast", tmp_path, mission), "--time-property", "")
    assert result.exit_code in (0, 1), result.output
    assert "exp_mission_time" not in result.stdout


@pytest.mark.parametrize("value", ["-5", "-0.5", "nan", "inf", "abc", ""])
def test_fade_at_cycle_must_be_a_cycle(value: str) -> None:
    result = run("phm", "fade", str(EXAMPLES / "cycles.csv"), "--at-cycle", value)
    assert_one_error(result, f"--at-cycle {value or repr('')}: must be a cycle number >= 0")


@pytest.mark.parametrize("value", ["0", "-1", "0.0", "nan", "inf", "5Ah"])
def test_levels_capacity_must_be_positive(value: str) -> None:
    result = run("phm", "levels", str(EXAMPLES / "discharge.csv"), "--capacity-ah", value)
    assert_one_error(result, f"--capacity-ah {value}:", "positive")


def test_fade_config_and_write_together_refused(tmp_path: Path, mission: Path) -> None:
    other = tmp_path / "other.yaml"
    other.write_text("battery:\n  max_recharges: 20\n")
    result = run("phm", "fade", str(EXAMPLES / "cycles.csv"), "--config", str(other),
                 "--write", str(mission))
    assert_one_error(result, "--config", "--write")
    assert other.read_text() == "battery:\n  max_recharges: 20\n"


def test_fade_invalid_merge_writes_no_figure(tmp_path: Path) -> None:
    config = tmp_path / "m.yaml"
    config.write_text("battery:\n  max_recharges: 200  # long missions\n")
    cycles = np.arange(0, 101, 10.0)
    log = cycles_csv(tmp_path / "cycles.csv", cycles, 6.0 - 0.03 * cycles)
    before = files(tmp_path)
    result = run("phm", "fade", str(log), "--write", str(config), "--plot",
                 str(tmp_path / "f.png"))
    assert result.exit_code == 2 and "max_recharges" in result.stderr
    assert files(tmp_path) == before


def test_csv_extra_cell_is_located(tmp_path: Path) -> None:
    path = tmp_path / "cycles.csv"
    path.write_text("cycle,capacity_ah\n0,11\n1,10.9,7\n2,10.8\n")
    assert_one_error(run("phm", "fade", str(path)),
                     f"{path}:3:8: row 2 has 3 cells, the header has 2 (cycle,capacity_ah)")


def test_csv_with_bom_is_read(tmp_path: Path) -> None:
    path = tmp_path / "cycles.csv"
    path.write_bytes(b"\xef\xbb\xbfcycle,capacity_ah\n0,11\n100,10.99\n200,10.98\n")
    result = run("phm", "fade", str(path))
    assert result.exit_code == 0, result.output
    assert "capacity_ah: 11\n" in result.stdout


def test_csv_non_utf8_byte_is_located(tmp_path: Path) -> None:
    path = tmp_path / "cycles.csv"
    path.write_bytes(b"cycle,capacity_ah\n0,11\n1,10\xff9\n2,10.8\n")
    assert_one_error(run("phm", "fade", str(path)), f"{path}:3:5: not UTF-8 text (byte 0xff)")


def test_user_text_printed_as_typed(tmp_path: Path) -> None:
    png = tmp_path / "[bold]my:warning:fade.png"
    result = run("phm", "fade", str(EXAMPLES / "cycles.csv"), "--plot", str(png))
    assert result.exit_code == 0, result.output
    assert f"wrote {png}\n" in result.stderr
    bad = tmp_path / "[red]my:warning:c.csv"
    bad.write_text("cycle,capacity_ah\n0,11\n1,x\n2,10\n")
    assert_one_error(run("phm", "fade", str(bad)), f"{bad}:3: row 2")


def test_write_path_printed_as_typed(tmp_path: Path) -> None:
    config = tmp_path / "[bold]m:warning:.yaml"
    config.write_text("battery:\n  max_recharges: 50\n")
    result = run("phm", "fade", str(EXAMPLES / "cycles.csv"), "--write", str(config))
    assert result.exit_code == 0, result.output
    assert result.stderr == f"wrote {config}\n"


def test_simulate_output_checked_before_pybamm(tmp_path: Path) -> None:
    (tmp_path / "discharge.csv").write_text("mine\n")
    result = run("phm", "simulate", "--power-w", "10", "-o", str(tmp_path))
    assert_one_error(result, "discharge.csv", "--force")
    assert (tmp_path / "discharge.csv").read_text() == "mine\n"
    afile = tmp_path / "afile"
    afile.write_text("")
    assert_one_error(run("phm", "simulate", "--power-w", "10", "-o", str(afile)),
                     "is a file, not a folder")


@pytest.mark.parametrize("command", ["fade", "recheck", "forecast"])
@pytest.mark.parametrize(("capacities", "expected"), [
    # squaring 1e308 overflowed in the fit's AIC: an OverflowError traceback (falling:
    # a flat log is refused before any fit)
    ((1e308, 9.9e307, 9.8e307), "no meaningful fade fit"),
    # a fit beyond the model's integers, whose fade was written as 0
    ((1e300, 9e299, 8e299, 7e299), "7e+300 units of battery.resolution_ah (0.1); the model's "
                                   "32-bit integers hold at most 1,073,741,823"),
    ((1.1e7, 1.09e7, 1.08e7, 1.07e7), "the fitted fade 0.000935/cycle would round to 0"),
], ids=["1e308", "1e300", "1e7"])
def test_capacities_beyond_the_model_are_refused(tmp_path: Path, mission: Path, command: str,
                                                 capacities: tuple[float, ...],
                                                 expected: str) -> None:
    log = tmp_path / "cycles.csv"
    log.write_text("cycle,capacity_ah\n" + "".join(
        f"{10 * i},{c!r}\n" for i, c in enumerate(capacities)))
    args = {"fade": ["phm", "fade", str(log)],
            "recheck": ["recheck", str(mission), "--cycles", str(log), *SMALL],
            "forecast": ["phm", "forecast", str(mission), "--cycles", str(log), "--horizon",
                         "10", *SMALL]}[command]
    before = files(tmp_path)
    assert_one_error(run(*args), expected)
    assert files(tmp_path) == before


@pytest.mark.parametrize("command", ["fade", "recheck"])
@pytest.mark.parametrize(("rows", "reason"), [
    # exp() of the log-linear start overflowed: an OverflowError traceback
    ("1,1e308\n2,1e307\n3,1e306\n4,1e305\n", "math range error"),
    # numpy's overflow warnings, LAPACK's "illegal value" lines, then a fit (exit 0)
    ("0,10\n1e300,9\n2e300,8\n3e300,7\n", "overflow encountered"),
    # cycles 1e-300 apart: numpy's divide-by-zero warnings, then "SVD did not converge"
    ("0,10\n1e-300,9\n2e-300,8\n3e-300,7\n", "divide by zero"),
], ids=["capacity-1e308", "cycles-1e300", "cycles-1e-300"])
def test_fits_beyond_floating_point_are_refused(tmp_path: Path, mission: Path, command: str,
                                                rows: str, reason: str) -> None:
    log = tmp_path / "cycles.csv"
    log.write_text("cycle,capacity_ah\n" + rows)
    args = (["phm", "fade", str(log)] if command == "fade" else
            ["recheck", str(mission), "--cycles", str(log), *SMALL])
    before = files(tmp_path)
    assert_one_error(run(*args), f"{log}: column 'capacity_ah' against 'cycle': no meaningful "
                                 "fade fit", f"not computable in floating point ({reason}")
    assert files(tmp_path) == before


def test_at_cycle_too_far_ahead_blames_the_option() -> None:
    """The last logged row was blamed ("cycles.csv:33: row 30 ..."); the option is at fault,
    and the error says the largest value that works, which does work."""
    cycles = str(EXAMPLES / "cycles.csv")
    line = assert_one_error(run("phm", "fade", cycles, "--at-cycle", "1e9"),
                            "error: --at-cycle 1e9: too far beyond the log's last cycle 30: "
                            "the knee fit gives capacity -1.379e+06 Ah at cycle 1e+09")
    largest = int(line.rsplit("; the largest --at-cycle that works is ", 1)[1])
    assert run("phm", "fade", cycles, "--at-cycle", str(largest)).exit_code == 0
    assert_one_error(run("phm", "fade", cycles, "--at-cycle", str(largest + 1)),
                     f"--at-cycle {largest + 1}: too far beyond")


def test_horizon_too_far_ahead_blames_the_option(mission: Path) -> None:
    cycles = str(EXAMPLES / "cycles.csv")
    line = assert_one_error(run("phm", "forecast", str(mission), "--cycles", cycles,
                                "--horizon", "10000000", *SMALL),
                            "error: --horizon 10000000: too far beyond the log's last cycle 30: "
                            "the knee fit gives capacity")
    largest = int(line.rsplit("; the largest --horizon that works is ", 1)[1])
    # The reach is the fade fit's under the config's battery: --at-cycle agrees.
    fade = ("phm", "fade", cycles, "--config", str(mission), "--at-cycle")
    assert run(*fade, str(30 + largest)).exit_code == 0
    assert_one_error(run(*fade, str(31 + largest)), "too far beyond")


@pytest.mark.parametrize(("volts", "expected"), [
    ("-25,-24.9,-20", ":2: row 1, column 'voltage_v': must be > 0, got -25 V"),
    ("1e30,9e29,8e29", ":2: row 1, column 'voltage_v': 1e+30 V is not a plausible battery"),
], ids=["negative", "1e30"])
def test_levels_voltage_out_of_range(tmp_path: Path, volts: str, expected: str) -> None:
    curve = tmp_path / "discharge.csv"
    curve.write_text("soc,voltage_v\n" + "".join(
        f"{soc},{v}\n" for soc, v in zip((1, 0.5, 0), volts.split(","), strict=True)))
    assert_one_error(run("phm", "levels", str(curve)), f"{curve}{expected}")


@pytest.mark.parametrize("step", ["1e-320", "0.000001", "0.0001"])
def test_levels_soc_step_too_fine_for_the_search(step: str) -> None:
    """The best thresholds are searched over m x m grid pairs: 1e-320 overflowed (a
    traceback), 0.0001 took 25 s and gigabytes, 0.000001 asked for 7 TiB."""
    assert_one_error(run("phm", "levels", str(EXAMPLES / "discharge.csv"), "--soc-step", step),
                     f"error: --soc-step {step}: puts more than 2,000 grid points",
                     "give a step of at least 0.0005")


@pytest.mark.parametrize("command", ["levels", "recheck"])
def test_a_flat_discharge_curve_is_refused(tmp_path: Path, mission: Path, command: str) -> None:
    """Every threshold pair fits a constant voltage equally well: the thresholds written
    (0.02/0.87) were arbitrary, with three equal levels; now a located error."""
    curve = tmp_path / "discharge.csv"
    curve.write_text("soc,voltage_v\n1,3.7\n0.5,3.7\n0,3.7\n")
    args = (["phm", "levels", str(curve)] if command == "levels" else
            ["recheck", str(mission), "--cycles", str(EXAMPLES / "cycles.csv"),
             "--discharge", str(curve), *SMALL])
    assert_one_error(run(*args), f"{curve}:4: row 3, column 'voltage_v': the voltage stays "
                                 "at 3.7 V over the whole log")


def test_recheck_change_of_an_undefined_value_is_blank(tmp_path: Path, mission: Path) -> None:
    """A discharge curve in single-cell volts makes every mission fail: the conditional
    expectations become undefined (nan, as check prints them) and their change was
    printed '+nan'; now it is left blank (JSON: null)."""
    curve = tmp_path / "discharge.csv"
    curve.write_text("soc,voltage_v\n1,4.2\n0.75,3.9\n0.5,3.7\n0.25,3.5\n0,3.0\n")
    result = run("recheck", str(mission), "--cycles", str(EXAMPLES / "cycles.csv"),
                 "--discharge", str(curve), *SMALL)
    assert result.exit_code == 0, result.output  # the mission states no requirement
    row = next(line for line in result.stdout.splitlines()
               if line.startswith("exp_mission_time_given_success"))
    assert row.split()[2:] == ["nan"] and "+nan" not in result.stdout
