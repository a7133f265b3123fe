"""Run many ``veribattery`` command lines of one source tree, each in a forked process.

    PYTHONPATH=TREE/src TREE_SRC=TREE/src python bench/tree_runner.py MODULE:FUNCTION \\
        CASES.json RESULTS.json [--jobs N] [--timeout S]

CASES.json is a list of ``{"id": ..., "argv": [...]}``; RESULTS.json receives, per case,
``{"id", "rc", "stdout", "stderr", "seconds"}`` (text decoded as UTF-8, an undecodable
byte written as ``\\xNN``, so byte differences survive).

Why a fork server: a fresh ``veribattery`` process spends ~0.35 s of CPU importing
before it reads its input, which across the ~500 peer-suite cases of two trees is most
of ``compare_values.py``'s run. Here the third-party libraries (numpy, scipy, pydantic,
click, ...) are imported once; each case then runs in its own forked child, so no case
sees another's module-level caches, through the tree's real console entry point (its
``sys.exit`` status, its stdout and stderr file descriptors). The tree's own modules are
imported in each child, as in a fresh process. Standard library only: it runs under
either tree.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import importlib
import json
import os
import resource
import sys
import tempfile
import time
import traceback
from typing import Any

#: Imported before forking: libraries both trees use whose import cannot change a value.
PRELOAD = ("numpy", "scipy.sparse", "scipy.sparse.linalg", "scipy.sparse.csgraph",
           "pydantic", "yaml", "click", "jinja2", "lark")


def _exit_code(exc: SystemExit) -> int:
    """The status a Python process exits with after *exc*, as the interpreter maps it."""
    if exc.code is None:
        return 0
    if isinstance(exc.code, int):
        return exc.code
    print(exc.code, file=sys.stderr)
    return 1


def _child(entry: tuple[str, str], argv: list[str], out: int, err: int) -> None:
    """The forked child: stdout and stderr to files, run the entry point, exit. Never returns."""
    code = 1
    try:
        devnull = os.open(os.devnull, os.O_RDONLY)
        os.dup2(devnull, 0)
        os.dup2(out, 1)
        os.dup2(err, 2)
        sys.argv = ["veribattery", *argv]
        module, function = entry
        try:
            main = getattr(importlib.import_module(module), function)
            code = _exit_code(SystemExit(main()))  # as its script runs it: sys.exit(main())
        except SystemExit as exc:
            code = _exit_code(exc)
        except BaseException:
            traceback.print_exc()
            code = 1
        atexit._run_exitfuncs()  # what interpreter shutdown would run
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(code)


def _read(fd: int) -> str:
    os.lseek(fd, 0, os.SEEK_SET)
    chunks = []
    while chunk := os.read(fd, 1 << 20):
        chunks.append(chunk)
    os.close(fd)
    return b"".join(chunks).decode("utf-8", errors="backslashreplace")


def _scratch_fd() -> int:
    """A read-write descriptor of a new file that is already unlinked."""
    fd, path = tempfile.mkstemp(prefix="tree_runner-")
    os.unlink(path)
    return fd


def run_all(entry: tuple[str, str], cases: list[dict[str, Any]], jobs: int,
            timeout: float) -> list[dict[str, Any]]:
    """Every case in a forked child, up to *jobs* at a time; results in case order."""
    pending = list(enumerate(cases))
    running: dict[int, tuple[int, int, int, float]] = {}  # pid -> (index, out, err, start)
    results: list[dict[str, Any]] = [{} for _ in cases]
    while pending or running:
        while pending and len(running) < jobs:
            index, case = pending.pop(0)
            out_fd, err_fd = _scratch_fd(), _scratch_fd()
            sys.stdout.flush()
            sys.stderr.flush()
            pid = os.fork()
            if pid == 0:
                _child(entry, list(case["argv"]), out_fd, err_fd)
            running[pid] = (index, out_fd, err_fd, time.perf_counter())
        pid, status = os.waitpid(-1, os.WNOHANG)
        if pid == 0:
            _kill_late(running, timeout)
            time.sleep(0.002)
            continue
        index, out_fd, err_fd, start = running.pop(pid)
        results[index] = {"id": cases[index]["id"], "rc": os.waitstatus_to_exitcode(status),
                          "stdout": _read(out_fd), "stderr": _read(err_fd),
                          "seconds": round(time.perf_counter() - start, 3)}
    return results


def _kill_late(running: dict[int, tuple[int, int, int, float]], timeout: float) -> None:
    """Kill the children that have run longer than *timeout* (their status says so)."""
    now = time.perf_counter()
    for pid, (_, _, err_fd, start) in running.items():
        if now - start > timeout:
            os.write(err_fd, f"\n[tree_runner: killed after {timeout:g} s]\n".encode())
            os.kill(pid, 9)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("entry", help="the console script's MODULE:FUNCTION")
    parser.add_argument("cases")
    parser.add_argument("results")
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--timeout", type=float, default=600.0)
    parser.add_argument("--memory-gb", type=float, default=6.0,
                        help="address-space limit of each case (0: none)")
    args = parser.parse_args()
    for name in PRELOAD:
        with contextlib.suppress(ImportError):
            importlib.import_module(name)
    import veribattery

    tree_src = os.path.realpath(os.environ["TREE_SRC"])
    if not os.path.realpath(veribattery.__file__).startswith(tree_src + os.sep):
        raise SystemExit(f"imported {veribattery.__file__}, not the tree in {tree_src}")
    if args.memory_gb > 0:
        limit = int(args.memory_gb * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    with open(args.cases, encoding="utf-8") as stream:
        cases = json.load(stream)
    module, function = args.entry.split(":")
    results = run_all((module, function), cases, max(1, args.jobs), args.timeout)
    with open(args.results, "w", encoding="utf-8") as stream:
        json.dump(results, stream)


if __name__ == "__main__":
    main()
