"""What the phm commands and recheck say to a person: the remedy suits the command at
hand, the thing at fault is named as typed, and a plain situation gets a plain sentence."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from veribattery.cli import cli

SMALL = ("--set", "farm.cols=3", "--set", "farm.rows=2", "--set", "farm.base=[0,0]")
#: Fades 0.0108/recharge: 200 recharges (the paper's cap) would empty the battery.
STEEP = "cycle,capacity_ah\n1,9.5\n2,9.4\n3,9.3\n"
CLASH = ("battery.max_recharges: 200 recharges x the fitted fade 0.0108/recharge >= 1, so "
         "the model's capacity would reach zero; ")


def run(*args: str) -> Result:
    return CliRunner().invoke(cli, list(args))


def one_error(result: Result) -> str:
    """The one ``error:`` line of a bad-input run (exit 2, nothing on stdout)."""
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    return lines[0]


@pytest.fixture
def steep(tmp_path: Path) -> Path:
    path = tmp_path / "cycles.csv"
    path.write_text(STEEP)
    return path


@pytest.fixture
def config(tmp_path: Path) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text("battery:\n  capacity_ah: 11\n  max_recharges: 200\n")
    return path


def test_fade_clash_with_max_recharges_names_the_key_not_a_cell(steep: Path) -> None:
    """It blamed "row 3, column 'capacity_ah'" and told to use --set, which phm fade
    does not have."""
    line = one_error(run("phm", "fade", str(steep)))
    assert line == (f"error: {CLASH}give --config (or --write) a config with "
                    "battery.max_recharges: 92 or less (without them, the paper's config "
                    "is used)")


@pytest.mark.parametrize("option", ["--config", "--write"])
def test_fade_clash_points_at_the_key_in_the_config_given(steep: Path, config: Path,
                                                          option: str) -> None:
    before = config.read_text()
    line = one_error(run("phm", "fade", str(steep), option, str(config)))
    assert line == (f"error: {config}:3:3: {CLASH}set battery.max_recharges: 92 or less in "
                    f"{config}")
    assert config.read_text() == before
    fixed = before.replace("200", "92")
    config.write_text(fixed)
    assert run("phm", "fade", str(steep), "--config", str(config)).exit_code == 0


def test_recheck_clash_suggests_set(steep: Path, config: Path) -> None:
    line = one_error(run("recheck", str(config), "--cycles", str(steep), *SMALL))
    assert line == (f"error: {config}:3:3: {CLASH}battery.max_recharges must be at most 92, "
                    "e.g. --set battery.max_recharges=92")
    fixed = run("recheck", str(config), "--cycles", str(steep), *SMALL,
                "--set", "battery.max_recharges=92")
    assert fixed.exit_code in (0, 1), fixed.output


def test_forecast_clash_names_the_set_that_gave_the_key(steep: Path, config: Path) -> None:
    line = one_error(run("phm", "forecast", str(config), "--cycles", str(steep),
                         "--horizon", "2", *SMALL, "--set", "battery.max_recharges=150"))
    assert line.startswith("error: --set battery.max_recharges: 150 recharges x the fitted "
                           "fade 0.0108/recharge >= 1")
    assert line.endswith("; battery.max_recharges must be at most 92, e.g. "
                         "--set battery.max_recharges=92")

