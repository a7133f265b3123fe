"""Every command as a user types it: in a real (pseudo-)terminal at 80 and 120 columns.

CliRunner never gives a command a terminal, so live progress, colours and the
terminal's width are only exercised here: what is asserted is what is on screen.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.cli.inputs import CASE1, EXAMPLES, SMALL, SYNTHESIS
from tests.cli.terminal import Screen, run_in_terminal
from tests.cli.test_contracts import DIE
from tests.patched_cli import last_error_line, run_patched

CYCLES = "cycle,capacity_ah\n" + "".join(f"{n},{11 - 0.004 * n:.4f}\n" for n in range(0, 60, 5))

#: (id, arguments, exit status, texts that must be on screen).
COMMANDS = [
    ("check", ["check", CASE1, *SMALL], 0, ["p_success", "exp_mission_time_given_success"]),
    ("check-exact", ["check", CASE1, *SMALL, "--exact"], 0, ["p/q:"]),
    ("emit", ["emit", CASE1, *SMALL, "-o", "model"], 0, ["model.prism"]),
    ("prism", ["prism", "die.pm", "--property", 'P=? [ F "six" ]'], 0, ["0.166666666667"]),
    ("sweep", ["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=10:11:0.5",
               "--vary", "battery.model=advanced,basic_high", "-j", "1"], 0,
     ["exp_recharges_given_success", "6 points: 6 checked, 0 failed"]),
    ("explain", ["explain", CASE1, *SMALL, "--top", "1"], 0, ["by k, cell", "Path 1"]),
    ("simulate", ["simulate", CASE1, *SMALL, "--runs", "50"], 0, ["95% CI"]),
    ("distribution", ["distribution", CASE1, *SMALL, "--deadline", "1d"], 0,
     ["P(success within 1d"]),
    ("phm-fade", ["phm", "fade", "cycles.csv"], 0, ["fade_per_recharge"]),
    ("phm-levels", ["phm", "levels", str(EXAMPLES / "discharge.csv")], 0,
     ["voltage_thresholds"]),
    ("phm-forecast", ["phm", "forecast", CASE1, *SMALL, "--cycles", "cycles.csv",
                      "--horizon", "20", "--step", "10"], 0, ["p_success"]),
    ("recheck", ["recheck", CASE1, *SMALL, "--cycles", "cycles.csv"], 0, ["before", "after"]),
    ("reproduce-table3", ["reproduce", "table3"], 0, ["exp_recharges", "42.7713"]),
    ("report", ["report", CASE1, *SMALL, "--runs", "50", "-o", "r.html"], 0, ["wrote r.html"]),
    ("synthesize", ["synthesize", CASE1, *SYNTHESIS, "--require", "0.9", "--require", "0.99",
                    "--require", "bs1"],
     1, ["optimum (Pmax)", "p_success >= 0.9", "7.3% faster", "FAIL p_success >= 0.99",
         "p_success >= BS1's 0.926991354356"]),
    ("help", ["--help"], 0, ["sweep", "130 interrupted"]),
]


@pytest.fixture()
def workdir(tmp_path: Path) -> Path:
    (tmp_path / "die.pm").write_text(DIE)
    (tmp_path / "cycles.csv").write_text(CYCLES)
    return tmp_path


@pytest.mark.parametrize("columns", [80, 120])
@pytest.mark.parametrize(("args", "status", "shown"), [c[1:] for c in COMMANDS],
                         ids=[c[0] for c in COMMANDS])
def test_command_in_a_terminal(workdir: Path, columns: int, args: list[str], status: int,
                               shown: list[str]) -> None:
    screen = run_in_terminal(args, columns, workdir)
    _assert_clean(screen, status, columns)
    for text in shown:
        assert text in screen.text, screen.text


def _assert_clean(screen: Screen, status: int, columns: int) -> None:
    assert screen.status == status, screen.text
    assert "Traceback" not in screen.text, screen.text
    assert screen.widest <= columns, "\n".join(line for line in screen.lines if len(line) > columns)


def test_user_text_is_shown_as_typed(workdir: Path) -> None:
    # rich would turn :b: and :warning: into emoji and [bold] into markup.
    (workdir / "my:warning:[bold]x.yaml").write_text("farm: {cols: 3, rows: 3, base: [0, 0]\n")
    screen = run_in_terminal(["check", "my:warning:[bold]x.yaml"], 80, workdir)
    assert screen.status == 2
    assert "my:warning:[bold]x.yaml" in screen.text, screen.text
    screen = run_in_terminal(["sweep", CASE1, *SMALL, "--vary", "battery.capacity_ah=a:b:c"],
                             80, workdir)
    assert screen.status == 2
    assert "a:b:c" in screen.text, screen.text


def test_interrupted_check_exits_130(workdir: Path) -> None:
    import signal
    import subprocess
    import sys
    import time

    # 357 points: far more than the 0.2 s before the signal can check
    process = subprocess.Popen(
        [sys.executable, "-c", "from veribattery.cli import main; main()", "sweep", CASE1,
         *SMALL, "--vary", "battery.capacity_ah=10:20:0.5",
         "--vary", "environment.p_wsp_c=0.1:0.9:0.05", "-j", "1"],
        cwd=workdir, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        # Ctrl-C as a terminal delivers it: a harness started in the background (`cmd &`
        # in a script) ignores SIGINT, and its children inherit that
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert process.stderr is not None
    process.stderr.readline()  # the first point's line: the sweep is under way
    time.sleep(0.2)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    assert b"interrupted" in stderr and b"Traceback" not in stderr


def test_running_out_of_memory_is_one_line_and_status_2(tmp_path: Path) -> None:
    """A solve past the build's memory guard that cannot allocate its arrays (numpy's
    MemoryError, raised here from inside the check of a real process) ends with one
    line, not numpy's traceback."""
    (tmp_path / "die.pm").write_text(DIE)
    starve = ("import veribattery.checker.kernels as kernels\n"
              "def starved(*args, **kwargs):\n"
              "    raise MemoryError('Unable to allocate 54.6 MiB for an array with shape "
              "(7156153,) and data type int64')\n"
              "kernels.until_probs = starved")
    done = run_patched(starve, ["prism", "die.pm", "--property", "P=? [ F d=6 ]"], tmp_path)
    assert last_error_line(done) == (
        "error: out of memory: Unable to allocate 54.6 MiB for an array with shape (7156153,) "
        "and data type int64: the model or its analysis needs more memory than this machine "
        "has available")


def test_a_config_too_fine_for_prisms_ints_fails_before_any_spinner(workdir: Path) -> None:
    # The ints' limits were checked when the model was rendered, inside the spinner
    # ("exploring states…" was drawn, then erased by the error).
    (workdir / "fine.yaml").write_text("strategy: {safe_t: 0.1000000000000000000001}\n")
    screen = run_in_terminal(["check", "fine.yaml"], 80, workdir)
    assert screen.status == 2
    assert "exploring states" not in screen.drawn, screen.drawn
    assert "safe_t: 0.1000000000000000000001 is too fine" in screen.text, screen.text


def test_a_constant_of_the_wrong_type_fails_without_a_spinner(tmp_path: Path) -> None:
    # The constants are resolved when the model is flattened, once the spinner was up:
    # "exploring states…" was drawn and erased in the same instant, then the error.
    (tmp_path / "die.pm").write_text(DIE.replace("module", "const int x;\nmodule", 1))
    screen = run_in_terminal(["prism", "die.pm", "--property", "P=? [ F d=x ]", "--const",
                              "x=true"], 80, tmp_path)
    assert screen.status == 2
    assert "exploring states" not in screen.drawn, screen.drawn
    assert "constant 'x' is an int, but was given the value 'true'" in screen.text, screen.text
