"""What the correctness sweeps over public model sets share (``bench_qvbench_mdp.py``,
``storm_testfiles_sweep.py``): reading a folder of a git repository, running one
veribattery or Storm process with a timeout, and naming the tree measured."""

from __future__ import annotations

import errno
import math
import os
import resource
import signal
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: Values agree to this relative tolerance ...
RELATIVE_TOLERANCE = 1e-6
#: ... or this absolute one, near 0.
ABSOLUTE_TOLERANCE = 1e-9

#: A value read off a tool's output: a number, a truth value, or none.
Number = float | bool | None


class GitFolder:
    """A folder of a repository: in a checkout's work tree, or at HEAD of a bare git
    directory (what the ``fetch`` of a mirror gives)."""

    def __init__(self, root: Path, folder: str) -> None:
        self.root = root
        self.prefix = folder
        self.folder: Path | None = root / folder
        if not self.folder.is_dir():
            self.folder = None
            if self._git("rev-parse", "--is-bare-repository") is None:
                raise SystemExit(f"--root {root}: neither a checkout holding {folder} "
                                 "nor a git directory")

    def _git(self, *args: str) -> bytes | None:
        """The output of git on the root (a bare git dir or a checkout), None on failure."""
        where = ["-C", str(self.root)] if self.folder else ["--git-dir", str(self.root)]
        done = subprocess.run(["git", *where, *args], capture_output=True, check=False)
        return done.stdout if done.returncode == 0 else None

    def commit(self) -> str:
        """The commit the files come from (a checkout's HEAD; its work tree is read)."""
        head = self._git("rev-parse", "HEAD")
        return head.decode().strip() if head else "unknown (not a git checkout)"

    def files(self, *subfolders: str) -> list[str]:
        """Every file under *subfolders*, relative to the folder, sorted."""
        if self.folder:
            return sorted(str(p.relative_to(self.folder)) for sub in subfolders
                          for p in (self.folder / sub).rglob("*") if p.is_file())
        listed = self._git("ls-tree", "-r", "--name-only", "HEAD", "--",
                           *(f"{self.prefix}/{sub}/" for sub in subfolders)) or b""
        return sorted(line.removeprefix(f"{self.prefix}/")
                      for line in listed.decode().splitlines())

    def read(self, path: str) -> bytes:
        """The file *path* (relative to the folder); FileNotFoundError if absent."""
        if self.folder:
            return (self.folder / path).read_bytes()
        found = self._git("show", f"HEAD:{self.prefix}/{path}")
        if found is None:
            raise FileNotFoundError(errno.ENOENT, "not at HEAD", path)
        return found


@dataclass
class Process:
    """What one run printed, its exit status (None: timed out) and wall time."""

    returncode: int | None
    stdout: str
    stderr: str
    wall_s: float


def run_process(command: list[str], cwd: Path, timeout: float,
                memory_bytes: int | None = None) -> Process:
    """Run *command* in *cwd* in a fresh process group (this tree's ``src`` first on
    ``PYTHONPATH``), killed after *timeout* seconds; with *memory_bytes*, under that
    address-space cap (``ulimit -v``)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        filter(None, [str(ROOT / "src"), env.get("PYTHONPATH", "")]))

    def capped() -> None:
        if memory_bytes is not None:
            resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))

    start = time.perf_counter()
    process = subprocess.Popen(command, cwd=cwd, env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, start_new_session=True,
                               preexec_fn=capped)
    try:
        out, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)  # the group this run started
        out, err = process.communicate()
        return Process(None, out, err, time.perf_counter() - start)
    return Process(process.returncode, out, err, time.perf_counter() - start)


def error_line(stderr: str) -> str:
    """The ``error:`` line of a refusal (else stderr's last line)."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error:")]
    return (errors or lines or [""])[-1]


def tree_commit() -> str:
    """This tree's commit, with ``+changes`` if its ``src`` differs."""
    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True,
                              check=False).stdout.strip()

    dirty = git("status", "--porcelain", "--untracked-files=no", "src")
    return (git("rev-parse", "--short", "HEAD") or "unknown") + (" +changes" if dirty else "")


def read_number(value: object) -> Number:
    """A value a tool printed, as a float (``"inf"``, ``"Infinity"``, ``"NaN"``), a truth
    value, or None."""
    if isinstance(value, bool):
        return value
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str):
        try:
            return float(value.replace("Infinity", "inf"))
        except ValueError:
            return None
    return None


def agree(ours: Number, reference: Number) -> bool:
    """Whether our value matches the reference: truth values exactly, infinities by sign,
    numbers to RELATIVE_TOLERANCE (ABSOLUTE_TOLERANCE near 0)."""
    if isinstance(ours, bool) or isinstance(reference, bool):
        return isinstance(ours, bool) and isinstance(reference, bool) and ours == reference
    if ours is None or reference is None or math.isnan(ours) or math.isnan(reference):
        return False
    if math.isinf(ours) or math.isinf(reference):
        return ours == reference
    return abs(ours - reference) <= max(RELATIVE_TOLERANCE * abs(reference), ABSOLUTE_TOLERANCE)
