"""What the phm commands and recheck say to a person: the remedy suits the command at
hand, the thing at fault is named as typed, and a plain situation gets a plain sentence."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from tests.cli.refusals import one_error
from tests.cli.terminal import run_in_terminal
from tests.phm.helpers import EXAMPLES
from veribattery.cli import cli

SMALL = ("--set", "farm.cols=3", "--set", "farm.rows=3", "--set", "farm.base=[0,0]")
#: Fades 0.0108/recharge: 200 recharges (the paper's cap) would empty the battery.
STEEP = "cycle,capacity_ah\n1,9.5\n2,9.4\n3,9.3\n"
CLASH = ("battery.max_recharges: 200 recharges x the fitted fade 0.0108/recharge >= 1, so "
         "the model's capacity would reach zero; ")


def run(*args: str) -> Result:
    return CliRunner().invoke(cli, list(args))


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



def _forecast(tmp_path: Path, *extra: str) -> Result:
    config = tmp_path / "m.yaml"
    config.write_text("battery:\n  capacity_ah: 11\n  max_recharges: 50\n")
    log = tmp_path / "c.csv"
    log.write_text("cycle,capacity_ah\n" + "".join(
        f"{c},{8.6 - 0.032 * c!r}\n" for c in range(0, 51, 5)))
    return run("phm", "forecast", str(config), "--cycles", str(log), *SMALL, *extra)


def test_forecast_exits_1_when_the_requirement_already_fails(tmp_path: Path) -> None:
    """'p_success >= 0.99 already fails now (cycle 30)' exited 0: a failing requirement
    exits 1, as in every command."""
    config = tmp_path / "small.yaml"
    config.write_text("farm:\n  cols: 3\n  rows: 2\n  base: [0, 0]\n"
                      "battery:\n  capacity_ah: 6\n  max_recharges: 8\n")
    result = run("phm", "forecast", str(config), "--cycles", str(EXAMPLES / "cycles.csv"),
                 "--horizon", "20", "--step", "10")
    assert result.exit_code == 1, result.output
    assert result.stdout.endswith("p_success >= 0.99 already fails now (cycle 30)\n")


@pytest.mark.parametrize(("horizon", "code", "said"), [
    ("5", 0, "holds at every checked age up to 5 cycles ahead"),
    ("20", 1, "stops holding after 8 more cycles"),
])
def test_forecast_exit_status_follows_the_horizon(tmp_path: Path, horizon: str, code: int,
                                                  said: str) -> None:
    result = _forecast(tmp_path, "--horizon", horizon, "--step", "5")
    assert result.exit_code == code, result.output
    assert said in result.stdout


def test_levels_soc_step_too_fine_names_the_option_and_a_clean_range() -> None:
    """It blamed the data file, on 'the SOC range 2.22e-16..1' (summation noise)."""
    line = one_error(run("phm", "levels", str(EXAMPLES / "discharge.csv"),
                         "--soc-step", "1e-9"))
    assert line == ("error: --soc-step 1e-9: puts more than 2,000 grid points on the log's SOC "
                    "range 0..1; give a step of at least 0.0005, e.g. 0.01")
    assert run("phm", "levels", str(EXAMPLES / "discharge.csv"),
               "--soc-step", "0.0005").exit_code == 0


def test_levels_capacity_too_large_names_the_option() -> None:
    """--capacity-ah 1e308 left the SOC at 1 throughout, and the error blamed the data:
    'the SOC range 1..1 spans fewer than 3 points ...; log a longer discharge'."""
    curve = str(EXAMPLES / "discharge.csv")
    line = one_error(run("phm", "levels", curve, "--capacity-ah", "1e308"))
    assert line == ("error: --capacity-ah 1e308: the log delivers 9.431 Ah, only 9.4e-308 of "
                    "that, so its SOC spans fewer than 3 points of the 0.01 SOC grid; give the "
                    "battery's full charge (at most 470 Ah for this log), or leave it out to "
                    "use the 9.431 Ah the log delivers")
    assert run("phm", "levels", curve, "--capacity-ah", "470").exit_code == 0


def test_levels_short_log_still_blames_the_file(tmp_path: Path) -> None:
    curve = tmp_path / "d.csv"
    curve.write_text("soc,voltage_v\n1,25\n0.995,24\n0.99,23\n")
    assert one_error(run("phm", "levels", str(curve))) == (
        f"error: {curve}: the SOC range 0.99..1 spans fewer than 3 points of the 0.01 SOC "
        "grid; log a longer discharge")


FLAT = "cycle,capacity_ah\n1,9.5\n2,9.5\n3,9.5\n"


@pytest.mark.parametrize("command", ["fade", "recheck", "forecast"])
def test_a_flat_capacity_log_is_said_plainly(tmp_path: Path, config: Path,
                                            command: str) -> None:
    """A new battery that has not faded yet got three fits' statistics ('linear:
    parameters not identifiable (infinite covariance); exponential: ...')."""
    log = tmp_path / "flat.csv"
    log.write_text(FLAT)
    args = {"fade": ["phm", "fade", str(log)],
            "recheck": ["recheck", str(config), "--cycles", str(log), *SMALL],
            "forecast": ["phm", "forecast", str(config), "--cycles", str(log), *SMALL]}
    assert one_error(run(*args[command])) == (
        f"error: {log}: column 'capacity_ah': capacity does not change over the log (9.5 Ah "
        "at cycles 1..3); no fade can be fitted yet: log more cycles, and keep the config's "
        "battery.fade_per_recharge until then")


@pytest.mark.parametrize(("option", "remedy"), [
    ("--cycles", "give the path of the capacity log (cycle,capacity_ah)"),
    ("--discharge", "give the path of the discharge log (soc,voltage_v or "
                    "time_s,voltage_v,current_a)"),
])
def test_recheck_missing_data_file_names_the_option(tmp_path: Path, config: Path,
                                                    option: str, remedy: str) -> None:
    """It said 'cannot read nope.csv: No such file or directory', not which option."""
    files = {"--cycles": str(EXAMPLES / "cycles.csv"),
             "--discharge": str(EXAMPLES / "discharge.csv"), option: "nope.csv"}
    args = [arg for name, path in files.items() for arg in (name, path)]
    line = one_error(run("recheck", str(config), *args, *SMALL))
    assert line == f"error: {option} nope.csv: no such file; {remedy}"


def test_forecast_missing_cycles_names_the_option(config: Path) -> None:
    line = one_error(run("phm", "forecast", str(config), "--cycles", "nope.csv", *SMALL))
    assert line.startswith("error: --cycles nope.csv: no such file; ")


@pytest.mark.parametrize("command", ["fade", "levels"])
def test_write_to_a_missing_config_says_to_create_it(tmp_path: Path, command: str,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """It said "cannot read config 'new.yaml'": neither --write nor that it must exist."""
    monkeypatch.chdir(tmp_path)
    data = EXAMPLES / ("cycles.csv" if command == "fade" else "discharge.csv")
    line = one_error(run("phm", command, str(data), "--write", "new.yaml"))
    assert line == ("error: --write new.yaml: no such file; --write merges into an existing "
                    "config: create it first (an empty file is the paper's config), or leave "
                    "--write out and paste the fragment printed")
    assert not (tmp_path / "new.yaml").exists()
    (tmp_path / "new.yaml").write_text("")
    assert run("phm", command, str(data), "--write", "new.yaml").exit_code == 0


def test_fade_missing_config_names_the_option(tmp_path: Path) -> None:
    line = one_error(run("phm", "fade", str(EXAMPLES / "cycles.csv"),
                         "--config", str(tmp_path / "none.yaml")))
    assert line == (f"error: --config {tmp_path / 'none.yaml'}: no such file; give an existing "
                    "config (leave --config out for the paper's)")


def _items(lines: tuple[str, ...], first: str, last: str) -> list[str]:
    """The screen lines from the one starting with *first* up to the one before *last*."""
    start = next(i for i, line in enumerate(lines) if line.startswith(first))
    end = next(i for i, line in enumerate(lines) if i > start and line.startswith(last))
    return list(lines[start:end])


def test_fade_items_keep_their_indent_when_wrapped(tmp_path: Path) -> None:
    """At 80 columns 'b2=0.0013788, nk=18' continued the knee's item in column 0."""
    screen = run_in_terminal(["phm", "fade", str(EXAMPLES / "cycles.csv")], 80, tmp_path)
    assert screen.status == 0, screen.text
    items = _items(screen.lines, "  knee: ", "choice: ")
    assert items[1] == "    b2=0.0013788, nk=18"
    assert all(line.startswith("  ") and len(line) <= 80 for line in items)


def test_recheck_items_keep_their_indent_when_wrapped(tmp_path: Path) -> None:
    screen = run_in_terminal(["recheck", str(EXAMPLES / "mission.yaml"), "--cycles",
                              str(EXAMPLES / "cycles.csv"), "--discharge",
                              str(EXAMPLES / "discharge.csv"), *SMALL], 60, tmp_path)
    assert screen.status in (0, 1), screen.text
    items = _items(screen.lines, "  battery.capacity_ah: ", "property ")
    assert any(line.startswith("    ") for line in items)  # some did wrap, at 60
    assert all(line.startswith("  ") and len(line) <= 60 for line in items)


def test_the_docs_recheck_example_is_what_the_command_prints(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The page showed 3 of the 16 moved parameters and no header, with a comment
    after a line; it now shows the whole output, and this keeps it so."""
    command = ("veribattery recheck examples/phm/mission.yaml --cycles "
               "examples/phm/cycles.csv --discharge examples/phm/discharge.csv")
    doc = (EXAMPLES.parents[1] / "docs" / "commands" / "phm.md").read_text()
    shown = doc.split(f"  $ {command}\n", 1)[1].split("  ```", 1)[0].splitlines()
    monkeypatch.chdir(EXAMPLES.parents[1])
    result = run(*command.split()[1:])
    assert result.exit_code == 1, result.output
    assert [line[2:] for line in shown] == result.stdout.splitlines()
