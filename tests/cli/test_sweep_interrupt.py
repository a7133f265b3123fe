"""Ctrl-C on sweeps run by worker processes, delivered as a terminal delivers it: SIGINT
to the whole process group, the sweep's process and its workers alike.

The sweep's process handles it: it stops its workers, says where the finished points
are kept and exits with status 130 at once; the workers print nothing. A parallel
sweep used to print "interrupted" and then wait forever for its workers, and each
worker printed its own KeyboardInterrupt traceback.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from contextlib import suppress
from pathlib import Path

import pytest

from tests.cli.inputs import CASE1, SMALL

#: How long an interrupted command may take to exit before the test calls it hung.
HUNG_S = 60

#: 357 points of the small farm: far more than the workers check before the signal.
MANY_POINTS = ("--vary", "battery.capacity_ah=10:20:0.5",
               "--vary", "environment.p_wsp_c=0.1:0.9:0.05")


def _start(args: list[str], cwd: Path) -> subprocess.Popen[bytes]:
    """``veribattery ARGS`` in a session (and process group) of its own, as a shell runs
    a foreground job; SIGINT restored to its default (a harness started in the
    background ignores it, and its children would inherit that)."""
    return subprocess.Popen(
        [sys.executable, "-c", "from veribattery.cli import main; main()", *args],
        cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        preexec_fn=lambda: (signal.signal(signal.SIGINT, signal.SIG_DFL), os.setsid()))


def _read_until(process: subprocess.Popen[bytes], text: bytes) -> bytes:
    """stderr up to and including the first line holding *text*."""
    assert process.stderr is not None
    seen = b""
    while text not in seen:
        line = process.stderr.readline()
        assert line, f"ended before {text!r}: {seen.decode()}"
        seen += line
    return seen


def _ctrl_c(process: subprocess.Popen[bytes]) -> None:
    """Ctrl-C: SIGINT to the process group (nothing when the group is gone already)."""
    with suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGINT)


def _finish(process: subprocess.Popen[bytes], seen: bytes) -> str:
    """Everything the process wrote on stderr, once it has exited (killed if hung)."""
    try:
        _, rest = process.communicate(timeout=HUNG_S)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        pytest.fail(f"still running {HUNG_S} s after Ctrl-C: {seen.decode()}")
    return (seen + rest).decode()


def _assert_group_gone(group: int) -> None:
    """No process of the group (the sweep's workers) outlives the sweep."""
    deadline = time.monotonic() + HUNG_S
    while time.monotonic() < deadline:
        try:
            os.killpg(group, 0)
        except ProcessLookupError:
            return
        time.sleep(0.1)
    os.killpg(group, signal.SIGKILL)
    pytest.fail("worker processes outlived the interrupted sweep")


@pytest.mark.parametrize("presses", [1, 2], ids=["once", "again-while-exiting"])
def test_ctrl_c_stops_a_parallel_sweep_at_once(tmp_path: Path, presses: int) -> None:
    results = tmp_path / "r.csv"
    sweep = _start(["sweep", CASE1, *SMALL, *MANY_POINTS, "-j", "2", "-o", str(results)],
                   tmp_path)
    seen = _read_until(sweep, b"[1/357]")  # a worker has checked a point
    _ctrl_c(sweep)
    if presses == 2:  # pressed again while the sweep stops its workers and exits
        seen += _read_until(sweep, b"interrupted")
        _ctrl_c(sweep)
    stderr = _finish(sweep, seen)
    assert sweep.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    assert stderr.splitlines()[-1] == (
        f"interrupted; finished points are kept in {results}: rerun to resume")
    _assert_group_gone(sweep.pid)
    header, *rows = results.read_text().splitlines()
    assert header.startswith("point,battery.capacity_ah,environment.p_wsp_c,property,")
    assert rows and all(row.count(",") == header.count(",") for row in rows)


def test_ctrl_c_stops_a_sweep_on_a_local_dask_cluster_without_tracebacks(
        tmp_path: Path) -> None:
    """``--scheduler local``: the cluster's nanny and worker processes are in the
    terminal's process group too. They start with SIGINT held, so only the sweep's
    process handles Ctrl-C; before, each printed "Process Dask Worker process (from
    Nanny)" and a KeyboardInterrupt traceback (four of them on two workers), the workers
    logged each cancelled task as a warning, and under load the client, interrupted
    inside a call, printed a traceback from its ``__del__`` at exit."""
    pytest.importorskip("distributed")
    results = tmp_path / "r.csv"
    sweep = _start(["sweep", CASE1, *SMALL, *MANY_POINTS, "--scheduler", "local", "-j", "2",
                    "-o", str(results)], tmp_path)
    seen = _read_until(sweep, b"[1/357]")
    _ctrl_c(sweep)
    stderr = _finish(sweep, seen)
    assert sweep.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    assert [line for line in stderr.splitlines() if not line.startswith("[")] == [
        "structure reuse: 357 points share 21 state spaces; running on Dask scheduler "
        "local (2 workers)",
        f"interrupted; finished points are kept in {results}: rerun to resume"]
    _assert_group_gone(sweep.pid)
    header, *rows = results.read_text().splitlines()
    assert rows and all(row.count(",") == header.count(",") for row in rows)


def _children(pid: int) -> set[int]:
    """The live child processes of *pid* (Linux /proc)."""
    found = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            with suppress(OSError):  # (gone meanwhile)
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
                if int(fields[1]) == pid and fields[0] != "Z":
                    found.add(int(entry.name))
    return found


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_ctrl_c_as_workers_start_names_the_results_file(tmp_path: Path) -> None:
    """Ctrl-C once both workers are there (still importing, or checking): none prints
    a traceback, and the message names the results file, not the folder it is in."""
    process = _start(["reproduce", "table3", "-o", "out", "-j", "2"], tmp_path)
    seen = _read_until(process, b"running on 2 local worker processes")
    deadline = time.monotonic() + HUNG_S
    while len(_children(process.pid)) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    _ctrl_c(process)
    stderr = _finish(process, seen)
    assert process.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    assert stderr.splitlines()[-1] == (
        "interrupted; finished points are kept in out/table3_sweep.csv: rerun to resume")
    _assert_group_gone(process.pid)
