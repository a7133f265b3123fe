"""Every value of a base revision and of the working tree, compared byte for byte.

    python bench/compare_values.py BASE [-j 2] [--only check,prism,emit] [--peer-tests DIR]
    make compare BASE=8887d91

BASE is checked out with ``git worktree add`` into a temporary folder (or given as a
checkout with ``--base-dir``); the working tree is this repository as it is on disk.
Both run under this interpreter with ``PYTHONPATH=<tree>/src``. For each tree:

- ``check``: ``veribattery check CONFIG --format json`` on every config under configs/;
- ``prism``: every entry of the PRISM peer suites (prism, prism-extended,
  prism-examples), run as their harness ``prism_suite.py`` runs it:
  ``veribattery prism MODEL --props FILE --property I [--const K=V ...] --json``;
- ``emit``: ``veribattery emit CONFIG -o DIR`` on every config: what it prints and
  every file it writes.

Exit status, stdout, stderr and written files must be identical after normalisation:
``"timings_s": {...}`` (stage timings, the only part of the JSON that changes run to
run) is blanked, and the trees' own folders and the output folders are replaced by
placeholders. The report gives the count of identical cases per kind, the peer
harness's pass counts per tree, then every difference: JSON as ``key.path: base ->
work``, other text as a unified diff. A case the base rejects as a usage error (an
option or command it does not have yet) is listed apart, as not comparable. Exit
status 1 if anything differs or is not comparable (``--allow-incomparable``: only
differences count).

Each case runs in its own forked process of a per-tree server that imports the
third-party libraries once (``tree_runner.py``); ``--isolation process`` runs every case
as a whole new process instead (about three times slower).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import difflib
import importlib.util
import json
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

from trees import REPO, Tree, base_tree, default_peer_tests, working_tree

HERE = Path(__file__).resolve().parent
KINDS = ("check", "prism", "emit")
SUITES = ("prism", "prism-extended", "prism-examples")
#: Stage timings in the JSON of check and prism: blanked before comparing.
TIMINGS = re.compile(r'"timings_s": \{[^{}]*\}')
#: What click (and veribattery's one-line usage errors) say about an unknown option.
UNKNOWN_OPTION = re.compile(r"no such option|no such command|unexpected extra argument",
                            re.IGNORECASE)
OUT = "{out}"  # stands for the case's own output folder in an argv


@dataclass(frozen=True)
class Case:
    """One command line, run in both trees."""

    kind: str
    id: str
    argv: tuple[str, ...]
    entry: dict[str, Any] | None = None  # the peer-suite entry, for the harness's verdict


@dataclass
class Outcome:
    """What one case did in one tree, normalised."""

    rc: int
    stdout: str
    stderr: str
    files: dict[str, str] = field(default_factory=dict)


# ---------------------------------------------------------------------------
# Cases
# ---------------------------------------------------------------------------


def configs() -> list[Path]:
    """Every config under configs/, sorted."""
    found = sorted({*REPO.glob("configs/**/*.yaml"), *REPO.glob("configs/**/*.yml")})
    if not found:
        raise SystemExit(f"no configs under {REPO / 'configs'}")
    return found


def load_harness(peer_tests: Path) -> ModuleType:
    """The peer suites' own harness module (prism_suite.py), for its argv and verdicts."""
    path = peer_tests / "prism_suite.py"
    if not path.is_file():
        raise SystemExit(f"{path} not found: give --peer-tests DIR (or $VERIBATTERY_SHARED)")
    spec = importlib.util.spec_from_file_location("prism_suite", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def peer_cases(harness: ModuleType, peer_tests: Path) -> Iterator[Case]:
    """Every entry of the three DTMC suites, with the argv the harness would pass."""
    for suite in SUITES:
        manifest = peer_tests / suite / "manifest.json"
        if not manifest.is_file():
            raise SystemExit(f"{manifest} is missing")
        data, entries = harness.load_manifest(str(manifest))
        root = peer_tests / suite
        if isinstance(data, dict) and data.get("default_root"):
            root = root / data["default_root"]
        for entry in entries:
            argv = harness.entry_argv(entry, str(root), ["prism"])
            yield Case("prism", f"{suite}:{entry['id']}", tuple(argv), entry)


def all_cases(kinds: list[str], peer_tests: Path) -> tuple[list[Case], ModuleType | None]:
    """The cases of the chosen kinds, and the harness if peer cases are among them."""
    cases: list[Case] = []
    names = [str(c.relative_to(REPO)) for c in configs()]
    if "check" in kinds:
        cases += [Case("check", name, ("check", str(REPO / name), "--format", "json"))
                  for name in names]
    harness = None
    if "prism" in kinds:
        harness = load_harness(peer_tests)
        cases += list(peer_cases(harness, peer_tests))
    if "emit" in kinds:
        cases += [Case("emit", name, ("emit", str(REPO / name), "-o", OUT)) for name in names]
    return cases, harness


# ---------------------------------------------------------------------------
# Running
# ---------------------------------------------------------------------------


def out_folder(workdir: Path, tree: Tree, index: int) -> Path:
    return workdir / tree.label / f"case{index:04d}"


def concrete_argv(case: Case, out: Path) -> list[str]:
    return [str(out) if arg == OUT else arg for arg in case.argv]


def run_forked(tree: Tree, cases: list[Case], workdir: Path, jobs: int,
               timeout: float) -> list[dict[str, Any]]:
    """Every case through one ``tree_runner.py`` server of *tree*."""
    listed = [{"id": c.id, "argv": concrete_argv(c, out_folder(workdir, tree, i))}
              for i, c in enumerate(cases)]
    cases_file = workdir / f"{tree.label}-cases.json"
    results_file = workdir / f"{tree.label}-results.json"
    cases_file.write_text(json.dumps(listed), encoding="utf-8")
    module, function = tree.entry_point()
    proc = subprocess.run(
        [sys.executable, str(HERE / "tree_runner.py"), f"{module}:{function}", str(cases_file),
         str(results_file), "--jobs", str(jobs), "--timeout", str(timeout)],
        env=tree.env(), cwd=workdir, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SystemExit(f"{tree.label} runner failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    return list(json.loads(results_file.read_text(encoding="utf-8")))


def run_processes(tree: Tree, cases: list[Case], workdir: Path, jobs: int,
                  timeout: float) -> list[dict[str, Any]]:
    """Every case as a whole new process of *tree*'s command."""

    def one(index: int) -> dict[str, Any]:
        argv = [*tree.command(), *concrete_argv(cases[index], out_folder(workdir, tree, index))]
        try:
            proc = subprocess.run(argv, env=tree.env(), cwd=workdir, capture_output=True,
                                  timeout=timeout, check=False)
        except subprocess.TimeoutExpired:
            return {"rc": -9, "stdout": "", "stderr": f"killed after {timeout:g} s"}
        return {"rc": proc.returncode,
                "stdout": proc.stdout.decode("utf-8", errors="backslashreplace"),
                "stderr": proc.stderr.decode("utf-8", errors="backslashreplace")}

    with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
        return list(pool.map(one, range(len(cases))))


def outcomes(tree: Tree, cases: list[Case], raw: list[dict[str, Any]],
             workdir: Path) -> list[Outcome]:
    """The raw results of *tree*, normalised, with the files each case wrote."""
    found = []
    for index, result in enumerate(raw):
        out = out_folder(workdir, tree, index)
        places = {str(out): "<OUT>", str(tree.root): "<TREE>"}
        files = {}
        if out.is_dir():
            for path in sorted(p for p in out.rglob("*") if p.is_file()):
                text = path.read_bytes().decode("utf-8", errors="backslashreplace")
                files[str(path.relative_to(out))] = normalise(text, places)
        found.append(Outcome(result["rc"], normalise(result["stdout"], places),
                             normalise(result["stderr"], places), files))
    return found


def normalise(text: str, places: dict[str, str]) -> str:
    """*text* with its timings blanked and run-specific folders named by placeholders."""
    for path, name in places.items():
        text = text.replace(path, name)
    return TIMINGS.sub('"timings_s": "<timings>"', text)


def run_tree(tree: Tree, cases: list[Case], workdir: Path, jobs: int, timeout: float,
             isolation: str) -> list[Outcome]:
    runner = run_forked if isolation == "fork" else run_processes
    return outcomes(tree, cases, runner(tree, cases, workdir, jobs, timeout), workdir)


# ---------------------------------------------------------------------------
# Comparing
# ---------------------------------------------------------------------------


def json_or_none(text: str) -> Any:
    try:
        return json.loads(text)
    except ValueError:
        return None


def json_diff(base: Any, work: Any, path: str = "") -> Iterator[str]:
    """``path: base -> work`` for every leaf that differs (lists by index)."""
    if isinstance(base, dict) and isinstance(work, dict):
        for key in [*base, *(k for k in work if k not in base)]:
            sub = f"{path}.{key}" if path else str(key)
            if key not in work:
                yield f"{sub}: {json.dumps(base[key])} -> (absent)"
            elif key not in base:
                yield f"{sub}: (absent) -> {json.dumps(work[key])}"
            else:
                yield from json_diff(base[key], work[key], sub)
        if list(base) != [k for k in work if k in base]:
            yield f"{path or '(top)'}: key order {list(base)} -> {list(work)}"
    elif isinstance(base, list) and isinstance(work, list):
        for i in range(max(len(base), len(work))):
            sub = f"{path}[{i}]"
            if i >= len(work):
                yield f"{sub}: {json.dumps(base[i])} -> (absent)"
            elif i >= len(base):
                yield f"{sub}: (absent) -> {json.dumps(work[i])}"
            else:
                yield from json_diff(base[i], work[i], sub)
    elif type(base) is not type(work) or base != work:
        yield f"{path or '(top)'}: {json.dumps(base)} -> {json.dumps(work)}"


def text_diff(base: str, work: str, name: str) -> list[str]:
    """Structured for JSON that parses on both sides (and differs in values), else unified."""
    a, b = json_or_none(base), json_or_none(work)
    if a is not None and b is not None:
        lines = list(json_diff(a, b))
        if lines:
            return [f"{name} (JSON): {line}" for line in lines]
        # the same values, written differently (spacing, number format)
    return [line.rstrip("\n") for line in difflib.unified_diff(
        base.splitlines(), work.splitlines(), f"base {name}", f"work {name}", n=1, lineterm="")]


def differences(base: Outcome, work: Outcome) -> list[str]:
    """Human-readable lines for everything that differs; empty if identical."""
    lines = []
    if base.rc != work.rc:
        lines.append(f"exit status: {base.rc} -> {work.rc}")
    for name in ("stdout", "stderr"):
        a, b = getattr(base, name), getattr(work, name)
        if a != b:
            lines += text_diff(a, b, name)
    for name in sorted({*base.files, *work.files}):
        if name not in work.files:
            lines.append(f"file {name}: written by base only")
        elif name not in base.files:
            lines.append(f"file {name}: written by work only")
        elif base.files[name] != work.files[name]:
            lines += text_diff(base.files[name], work.files[name], f"file {name}")
    return lines


def base_lacks_option(base: Outcome, work: Outcome) -> bool:
    """The base refused the command line as a usage error the working tree accepts."""
    return (base.rc == 2 and work.rc != 2 and UNKNOWN_OPTION.search(base.stderr) is not None)


def harness_passes(harness: ModuleType, entry: dict[str, Any], got: Outcome) -> bool:
    """The peer harness's own verdict on one outcome (prism_suite.run_entry's rule)."""
    if harness.expects_error(entry):
        return bool(harness.error_outcome(got.rc, got.stdout, got.stderr)[0])
    found, value, _ = harness.extract_value(got.stdout)
    if not found or value is None:
        return False
    expected = harness.parse_value(entry["expected"])
    return bool(harness.values_match(expected, value, entry.get("rtol", 1e-6), 1e-12))


# ---------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------


def report(cases: list[Case], base: list[Outcome], work: list[Outcome],
           harness: ModuleType | None, max_lines: int, allow_incomparable: bool) -> int:
    """Print the summary and every difference; the exit status."""
    diffs: list[tuple[Case, list[str]]] = []
    incomparable: list[Case] = []
    for case, a, b in zip(cases, base, work, strict=True):
        lines = differences(a, b)
        if not lines:
            continue
        if base_lacks_option(a, b):
            incomparable.append(case)
        else:
            diffs.append((case, lines))
    for kind in KINDS:
        mine = [c for c in cases if c.kind == kind]
        if not mine:
            continue
        differ = sum(1 for c, _ in diffs if c.kind == kind)
        skipped = sum(1 for c in incomparable if c.kind == kind)
        line = f"{kind}: {len(mine)} cases, {len(mine) - differ - skipped} identical"
        line += f", {differ} differ" if differ else ""
        line += f", {skipped} not comparable (base lacks the option)" if skipped else ""
        print(line)
    if harness is not None:
        print_harness_counts(cases, base, work, harness)
    for case in incomparable:
        print(f"not comparable: {case.kind} {case.id}: the base rejects "
              f"`veribattery {' '.join(case.argv)}` as a usage error")
    for case, lines in diffs:
        print(f"\n== {case.kind} {case.id}")
        print(f"   veribattery {' '.join(case.argv)}")
        for line in lines[:max_lines]:
            print(f"   {line}")
        if len(lines) > max_lines:
            print(f"   ... {len(lines) - max_lines} more lines (--max-lines)")
    if diffs:
        print_places(diffs)
    verdict = f"{len(diffs)} case(s) DIFFER" if diffs else "IDENTICAL"
    if incomparable:
        verdict += f"; {len(incomparable)} case(s) NOT COMPARABLE (the base lacks an option)"
    print(f"\n{verdict}")
    return 1 if diffs or (incomparable and not allow_incomparable) else 0


def print_places(diffs: list[tuple[Case, list[str]]]) -> None:
    """How many cases differ at each place (a JSON key path, a file, stderr ...)."""
    places: dict[tuple[str, str], int] = {}
    for case, lines in diffs:
        seen = set()
        for line in lines:
            if line.startswith("--- base "):
                seen.add(line.removeprefix("--- base "))  # a unified diff's heading
            elif not line.startswith(("+++", "@@", " ", "+", "-")):  # not its body
                seen.add(line.split(": ")[0] if " (JSON): " not in line
                     else ": ".join(line.split(": ")[:2]))
        for place in seen:
            places[(case.kind, place)] = places.get((case.kind, place), 0) + 1
    print("\nDifferences by place (cases):")
    for (kind, place), count in sorted(places.items()):
        print(f"  {kind}: {place}: {count}")


def print_harness_counts(cases: list[Case], base: list[Outcome], work: list[Outcome],
                         harness: ModuleType) -> None:
    """Per suite: entries, and how many pass the harness's check in each tree."""
    for suite in SUITES:
        rows = [(c, a, b) for c, a, b in zip(cases, base, work, strict=True)
                if c.kind == "prism" and c.id.startswith(suite + ":")]
        assert all(c.entry is not None for c, _, _ in rows)
        passed_base = sum(harness_passes(harness, c.entry, a) for c, a, _ in rows)  # type: ignore[arg-type]
        passed_work = sum(harness_passes(harness, c.entry, b) for c, _, b in rows)  # type: ignore[arg-type]
        print(f"  peer suite {suite}: {len(rows)} entries; harness passes: "
              f"base {passed_base}, work {passed_work}")


def save(folder: Path, cases: list[Case], tree: Tree, got: list[Outcome]) -> None:
    """The normalised outcomes of *tree* as JSON, for a closer look."""
    folder.mkdir(parents=True, exist_ok=True)
    data = [{"kind": c.kind, "id": c.id, "argv": list(c.argv), **vars(o)}
            for c, o in zip(cases, got, strict=True)]
    (folder / f"{tree.label}.json").write_text(json.dumps(data, indent=1), encoding="utf-8")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n".join(__doc__.splitlines()[1:]))
    parser.add_argument("base", help="the base revision (commit, tag, branch)")
    parser.add_argument("--base-dir", type=Path, help="an existing checkout of the base to use")
    parser.add_argument("--only", default=",".join(KINDS),
                        help="comma-separated kinds: check,prism,emit (default all)")
    parser.add_argument("--peer-tests", type=Path, default=default_peer_tests(),
                        help="the folder holding prism_suite.py and the suites "
                             "(default $VERIBATTERY_SHARED/peer-tests or ../shared/peer-tests)")
    parser.add_argument("-j", "--jobs", type=int, default=2, help="cases at a time (default 2)")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per case")
    parser.add_argument("--isolation", choices=("fork", "process"), default="fork")
    parser.add_argument("--max-lines", type=int, default=40, help="diff lines shown per case")
    parser.add_argument("--allow-incomparable", action="store_true",
                        help="exit 0 even if the base rejects some cases as usage errors")
    parser.add_argument("--save", type=Path, help="write both trees' outcomes here as JSON")
    args = parser.parse_args()
    kinds = [k for k in args.only.split(",") if k]
    if unknown := set(kinds) - set(KINDS):
        parser.error(f"unknown kinds {sorted(unknown)}; choose from {KINDS}")
    started = time.perf_counter()
    cases, harness = all_cases(kinds, args.peer_tests.resolve())
    work = working_tree()
    with base_tree(args.base, args.base_dir) as base, \
            tempfile.TemporaryDirectory(prefix="veribattery-compare-") as tmp:
        print(f"base {args.base} ({base.revision}) against the working tree ({work.revision}): "
              f"{len(cases)} cases each, -j {args.jobs}", flush=True)
        got = run_both(base, work, cases, Path(tmp), args)
    if args.save:
        save(args.save, cases, base, got[0])
        save(args.save, cases, work, got[1])
    status = report(cases, got[0], got[1], harness, args.max_lines,
                    args.allow_incomparable)
    print(f"({time.perf_counter() - started:.0f} s)")
    sys.exit(status)


def run_both(base: Tree, work: Tree, cases: list[Case], workdir: Path,
             args: argparse.Namespace) -> tuple[list[Outcome], list[Outcome]]:
    """Both trees' outcomes; the trees run side by side when -j allows two processes."""
    for tree in (base, work):
        tree.compile()
    per_tree = max(1, args.jobs // 2)
    with concurrent.futures.ThreadPoolExecutor(max_workers=2 if args.jobs > 1 else 1) as pool:
        futures = [pool.submit(run_tree, tree, cases, workdir, per_tree, args.timeout,
                               args.isolation) for tree in (base, work)]
        return futures[0].result(), futures[1].result()


if __name__ == "__main__":
    main()
