"""Two source trees side by side: a base revision checked out beside the working tree.

Used by ``compare_values.py`` and ``compare_speed.py``. Both trees run under this
interpreter (the project's venv); ``PYTHONPATH=<tree>/src`` puts a tree's package ahead
of the venv's editable install, and every process checks that it imported the tree it
was meant to (:data:`CHECK_IMPORT`).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: A Python statement that stops the process unless ``veribattery`` comes from $TREE_SRC.
CHECK_IMPORT = (
    "import os, veribattery as _v; "
    "assert os.path.realpath(_v.__file__).startswith(os.path.realpath(os.environ['TREE_SRC'])"
    " + os.sep), f'imported {_v.__file__}, not the tree in ' + os.environ['TREE_SRC']"
)


@dataclass(frozen=True)
class Tree:
    """One source tree: where it is, and which revision it holds."""

    label: str
    root: Path
    revision: str

    @property
    def src(self) -> Path:
        return self.root / "src"

    def env(self) -> dict[str, str]:
        """The environment a process of this tree runs in."""
        return {**os.environ, "PYTHONPATH": str(self.src), "TREE_SRC": str(self.src)}

    def entry_point(self) -> tuple[str, str]:
        """(module, function) of the ``veribattery`` console script this tree declares."""
        scripts = tomllib.loads((self.root / "pyproject.toml").read_text())["project"]["scripts"]
        module, function = scripts["veribattery"].split(":")
        return module, function

    def command(self) -> list[str]:
        """argv prefix that runs this tree's ``veribattery`` command as a process."""
        module, function = self.entry_point()
        code = (f"{CHECK_IMPORT}; import sys; from {module} import {function}; "
                f"sys.argv[0] = 'veribattery'; sys.exit({function}())")
        return [sys.executable, "-c", code]

    def compile(self) -> None:
        """Byte-compile src/ as ``make bytecode`` does (PYTHONDONTWRITEBYTECODE may be set,
        and a tree without .pyc files pays ~0.4 s of compilation in every process)."""
        subprocess.run([sys.executable, "-m", "compileall", "-q", str(self.src)],
                       check=True, stdout=subprocess.DEVNULL)


def git(*args: str) -> str:
    """Run git in the repository; its stdout, stripped."""
    proc = subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True,
                          check=False)
    if proc.returncode != 0:
        raise SystemExit(f"git {' '.join(args)}: {proc.stderr.strip()}")
    return proc.stdout.strip()


def working_tree() -> Tree:
    """The tree this script lives in, as it is on disk (uncommitted edits included)."""
    head = git("rev-parse", "--short=12", "HEAD")
    dirty = git("status", "--porcelain", "--untracked-files=no")
    return Tree("work", REPO, head + ("+edits" if dirty else ""))


@contextlib.contextmanager
def base_tree(revision: str, existing: Path | None = None) -> Iterator[Tree]:
    """The *revision* checked out with ``git worktree add`` in a temporary folder (removed
    afterwards), or *existing*, a checkout the caller made (left as it is)."""
    if existing is not None:
        yield Tree("base", existing.resolve(), revision or str(existing))
        return
    commit = git("rev-parse", "--verify", "--quiet", f"{revision}^{{commit}}")
    folder = Path(tempfile.mkdtemp(prefix="veribattery-base-"))
    checkout = folder / re.sub(r"[^\w.-]", "_", revision)
    git("worktree", "add", "--detach", "--quiet", str(checkout), commit)
    try:
        yield Tree("base", checkout, commit[:12])
    finally:
        subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(checkout)],
                       capture_output=True, check=False)
        shutil.rmtree(folder, ignore_errors=True)
        subprocess.run(["git", "-C", str(REPO), "worktree", "prune"], capture_output=True,
                       check=False)


def default_peer_tests() -> Path:
    """Where the PRISM peer suites are: $VERIBATTERY_SHARED/peer-tests (as the tests read
    it), else ../shared/peer-tests beside the repository."""
    shared = Path(os.environ.get("VERIBATTERY_SHARED", REPO.parent / "shared"))
    return shared.resolve() / "peer-tests"
