"""veribattery against the results QVBS records for its PRISM-language MDPs and DTMCs.

A correctness sweep on public models that are not copied here: point ``--root`` at
the Quantitative Verification Benchmark Set (https://github.com/ahartmanns/qcomp),
either a checkout (the folder that holds ``benchmarks/``) or a bare git
directory, read at its HEAD. ``--type`` picks ``benchmarks/mdp`` (the default) or
``benchmarks/dtmc``. Per family (the PRISM-language ones in FAMILIES), the
instances that ``index.json`` gives at most ``--max-states`` states and at least
one recorded result are taken, smallest first, at most ``--per-family`` of them;
their model and properties files are written into a temporary folder. Each named
property of the properties file runs in a fresh process,

    python -m veribattery prism MODEL --props PROPS --property NAME --const K=V ... --json

with this tree's ``src`` first on ``PYTHONPATH``, a wall-clock timeout, and a build
capped at BUILD_CAP_FACTOR times ``--max-states`` states (index.json's count may be
mcsta's, far below the PRISM model's: rabin.5 has 157,464 there, 27 million in
Storm's run). Each properties file is parsed first (``parse_properties``): one that
veribattery cannot parse would fail every property in it, so then each property's
text is passed inline (``--property TEXT``, with the properties file's own constants
written in) and the row says so. Our value is
compared with the reference QVBS records (an exact result if there is one, else
Storm's, else any): relative tolerance 1e-6 (absolute 1e-9 near 0), truth values
exactly, infinities equal. A refusal (exit 2, an ``error:`` line) is a row, not a
failure; a mismatch, a traceback (an exit status other than 0 and 2, or
``Traceback`` on stderr) or a timeout makes the exit status 1. The Markdown table
is rewritten after every row, so a stopped run keeps its rows.

With ``--exact`` every run has ``--exact`` too, and where QVBS records an exact result
(a fraction) our exact value must be that fraction, digit for digit; other references
are compared as above.

    python bench/bench_qvbench_mdp.py --root ~/qcomp [--type dtmc] [--only firewire]
        [--max-states 1000000] [--per-family 4] [--timeout 300] [--exact] [--out FILE]

The report goes to ``docs/_bench/qvbench_mdp.md`` (``qvbench_dtmc.md`` for DTMCs;
``qvbench_mdp_exact.md``, ``qvbench_dtmc_exact.md`` with ``--exact``).
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
import sys
import tempfile
import time
from dataclasses import dataclass, field
from datetime import UTC, datetime
from fractions import Fraction
from pathlib import Path

from bench_scale import byte_compile_sources
from sweeps import (
    ROOT,
    GitFolder,
    Number,
    Process,
    agree,
    error_line,
    read_number,
    run_process,
    tree_commit,
)

#: The QVBS families written in the PRISM language (model and properties file), by type.
FAMILIES = {
    "mdp": ("eajs", "ij", "pacman", "philosophers-mdp", "pnueli-zuck", "rabin",
            "resource-gathering", "firewire_abst", "firewire_dl", "wlan_dl", "zeroconf_dl",
            "consensus", "csma", "wlan", "zeroconf", "firewire"),
    "dtmc": ("bluetooth", "brp", "coupon", "crowds", "egl", "haddad-monmege", "herman",
             "leader_sync", "nand", "oscillators"),
}
TITLES = {"mdp": "MDPs", "dtmc": "DTMCs"}
MODEL_SUFFIXES = (".prism", ".nm", ".pm")
#: A build stops (exit 2, a refusal) past this many times ``--max-states`` states.
BUILD_CAP_FACTOR = 10
#: Outcomes that make the exit status 1.
FAILURES = ("NO", "error", "timeout")



def read_json(source: GitFolder, path: str) -> dict[str, object]:
    """A JSON file of QVBS (which writes some with a byte-order mark)."""
    data = json.loads(source.read(path).decode("utf-8-sig"))
    assert isinstance(data, dict)
    return data


@dataclass(frozen=True)
class Reference:
    """A result QVBS records for one property of one instance."""

    value: object
    tool: str
    exact: bool
    #: From index.json (the curated one) rather than a ``results/`` file.
    curated: bool

    def rank(self) -> tuple[bool, bool, bool]:
        """Sort key: exact first, then Storm's, then index.json's own."""
        return (not self.exact, not self.tool.startswith("Storm"), not self.curated)


@dataclass
class Instance:
    """One model file of a family with one assignment of its open constants."""

    family: str
    model: str
    props: str
    constants: dict[str, object]
    #: index.json's state counts, each with the tool that counted.
    states: list[tuple[int, str]]
    references: dict[str, list[Reference]] = field(default_factory=dict)
    #: State counts in the ``results/`` runs, by tool.
    logged_states: dict[str, int] = field(default_factory=dict)

    @property
    def size(self) -> int:
        return max(number for number, _ in self.states)

    @property
    def label(self) -> str:
        consts = " ".join(f"{k}={literal(v)}" for k, v in self.constants.items())
        return f"{Path(self.model).stem} {consts}".strip()


def literal(value: object) -> str:
    """A constant's value as PRISM writes it (``true``, not ``True``)."""
    return str(value).lower() if isinstance(value, bool) else str(value)


def _assignment(items: object) -> dict[str, object]:
    """QVBS's ``[{"name": ..., "value": ...}]`` as a dict."""
    return {item["name"]: item["value"] for item in items or []}  # type: ignore[attr-defined]


def _same(a: dict[str, object], b: dict[str, object]) -> bool:
    """Equal assignments, ``True`` and ``1`` told apart."""
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def _tool(note: str) -> tuple[str, bool]:
    """An index.json note such as ``Storm/exact`` as (tool, exact)."""
    parts = note.split("/")
    return " ".join(parts), "exact" in parts[1:]


def _run_states(data: list[dict[str, object]]) -> int | None:
    """The state count a ``results/`` run logged (Storm says ``states``, mcsta ``States``)."""
    for group in data:
        if group.get("group") == "State space exploration":
            for item in group.get("values") or []:  # type: ignore[attr-defined]
                if str(item.get("name")).lower() == "states":
                    return int(item["value"])
    return None


def family_instances(source: GitFolder, family: str) -> list[Instance]:
    """The PRISM-language instances of *family* with a state count, and their references."""
    index = read_json(source, f"{family}/index.json")
    found: list[tuple[str, Instance]] = []
    for entry in index["files"]:  # type: ignore[attr-defined]
        original = entry.get("original-file") or []
        if len(original) != 2 or not original[0].endswith(MODEL_SUFFIXES):
            continue
        for values in entry.get("open-parameter-values") or []:
            states = [(int(s["number"]), s.get("note", "?")) for s in values.get("states") or []]
            if not states:
                continue
            instance = Instance(family, original[0], original[1],
                                _assignment(values.get("values")), states)
            for result in values.get("results") or []:
                tool, exact = _tool(result.get("note", "?"))
                instance.references.setdefault(result["property"], []).append(
                    Reference(result["value"], tool, exact, curated=True))
            found.append((entry["file"], instance))
    for listed in index.get("results") or []:  # type: ignore[attr-defined]
        path = listed if isinstance(listed, str) else listed["file"]
        run = read_json(source, f"{family}/{path}")
        tool_info = run["tool"]
        assert isinstance(tool_info, dict)
        variants = list(tool_info.get("variant") or [])
        tool = " ".join([tool_info["name"], *variants])
        constants = _assignment(run.get("open-parameter-values"))
        for jani, instance in found:
            if Path(str(run["file"])).name != jani or not _same(constants, instance.constants):
                continue
            data = run["data"]
            assert isinstance(data, list)
            logged = _run_states(data)
            if logged is not None:
                instance.logged_states[tool] = logged
            for item in data:
                if "property" in item and "value" in item:
                    instance.references.setdefault(item["property"], []).append(
                        Reference(item["value"], tool, "exact" in variants, curated=False))
    return [instance for _, instance in found if instance.references]


def select(instances: list[Instance], max_states: int, per_family: int) -> list[Instance]:
    """The smallest *per_family* instances of at most *max_states* states (stable order)."""
    small = [instance for instance in instances if instance.size <= max_states]
    return sorted(small, key=lambda instance: instance.size)[:per_family]


def _without_comments(text: str) -> str:
    return re.sub(r"//[^\n]*|/\*.*?\*/", "", text, flags=re.S)


def named_properties(text: str) -> dict[str, str]:
    """The named properties ``"name": text;`` of a properties file, in order."""
    named: dict[str, str] = {}
    for statement in _without_comments(text).split(";"):
        match = re.fullmatch(r'\s*"([^"]+)"\s*:\s*(.*?)\s*', statement, flags=re.S)
        if match:
            named[match.group(1)] = match.group(2)
    return named


def undefined_constants(text: str) -> set[str]:
    """The constants a properties file declares without a value (``const int B;``)."""
    return set(re.findall(r"\bconst\s+(?:(?:int|double|bool)\s+)?([A-Za-z_]\w*)\s*;",
                          _without_comments(text)))


def substituted(text: str, values: dict[str, object]) -> str:
    """*text* with the identifiers in *values* replaced by their values (not inside quotes)."""
    def swap(match: re.Match[str]) -> str:
        word = match.group(0)
        return literal(values[word]) if word in values else word

    return re.sub(r'"[^"]*"|[A-Za-z_]\w*', swap, text)


def reference_value(value: object) -> Number:
    """A value as QVBS writes it (a number, ``{"num", "den", "approx"}``, ``"true"``, ...)."""
    if isinstance(value, dict):
        if "num" in value and "den" in value:
            return float(Fraction(int(value["num"]), int(value["den"])))
        return reference_value(value.get("approx"))
    if isinstance(value, str):
        word = value.strip().lower()
        if word in ("true", "false"):
            return word == "true"
        return read_number(word.replace("∞", "inf"))
    return read_number(value)


def show(value: Number) -> str:
    """A value to 12 significant digits (truth values as ``true``/``false``)."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return literal(value)
    return f"{value:.12g}"


@dataclass
class Row:
    """The outcome of one property of one instance."""

    instance: Instance
    prop: str
    command: list[str]
    outcome: str  # yes, NO, refused, error, timeout, no reference
    wall_s: float
    inline: bool = False
    states: int | None = None
    #: States left unexpanded, every property decided there (``stopped_states``).
    stopped: int = 0
    value: Number = None
    bounds: tuple[Number, Number] | None = None
    reference: Reference | None = None
    message: str = ""
    warnings: list[str] = field(default_factory=list)
    stderr: str = ""
    exactly: bool = False  # compared with an exact reference, fraction for fraction


def outcome_row(instance: Instance, prop: str, command: list[str], done: Process,
                inline: bool) -> Row:
    """A row from one finished (or timed-out) run."""
    references = sorted(instance.references.get(prop, []), key=Reference.rank)
    row = Row(instance, prop, command, "", done.wall_s, inline,
              reference=references[0] if references else None, stderr=done.stderr,
              warnings=[line.strip() for line in done.stderr.splitlines()
                        if line.startswith("warning:")])
    if done.returncode is None:
        row.outcome = "timeout"
        return row
    if "Traceback" in done.stderr or done.returncode not in (0, 2):
        row.outcome, row.message = "error", f"exit {done.returncode}: {error_line(done.stderr)}"
        return row
    if done.returncode == 2:
        row.outcome, row.message = "refused", error_line(done.stderr)
        return row
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    try:
        output = json.loads(lines[-1])
        result = output["results"][0]
    except (IndexError, KeyError, ValueError):
        row.outcome, row.message = "error", "exit 0 without a JSON result"
        return row
    row.states = output.get("model", {}).get("states")
    row.stopped = int(output.get("model", {}).get("stopped_states", 0))
    row.value = read_number(result.get("value"))
    bounds = result.get("bounds")
    if isinstance(bounds, list) and len(bounds) == 2:
        row.bounds = (read_number(bounds[0]), read_number(bounds[1]))
    if row.reference is None:
        row.outcome = "no reference"
        return row
    exact = exact_reference(row.reference.value)
    if exact is not None and "exact" in result:  # (an --exact run, an exact reference)
        row.exactly = True
        row.outcome = "yes" if _fraction(result["exact"]) == exact else "NO"
    else:
        row.outcome = "yes" if agree(row.value, reference_value(row.reference.value)) else "NO"
    return row


def exact_reference(value: object) -> Fraction | None:
    """The exact result QVBS records (``{"num", "den", ...}``), or None."""
    if isinstance(value, dict) and "num" in value and "den" in value:
        return Fraction(int(value["num"]), int(value["den"]))
    return None


def _fraction(text: object) -> Fraction | None:
    """Our JSON's ``"exact"`` (``"p/q"``; ``"Infinity"``: None)."""
    try:
        return Fraction(str(text))
    except (ValueError, ZeroDivisionError):
        return None


def parse_error(props: str, folder: Path, timeout: float) -> str | None:
    """The first line of veribattery's error for the properties file *props* (under
    *folder*), or None where it parses. A property that parses but is outside the
    language, or that a model refuses, is that property's row, not the file's."""
    command = [sys.executable, "-c", "import sys; from pathlib import Path; from "
               "veribattery.lang import parse_properties; parse_properties(Path(sys.argv[1]))",
               props]
    done = run_process(command, folder, timeout)
    if done.returncode == 0:
        return None
    return next((line for line in reversed(done.stderr.splitlines()) if line.strip()),
                "(no message)")


def check(instance: Instance, prop: str, folder: Path, timeout: float, cap: int,
          unreadable: dict[str, str | None], *, exact: bool = False) -> Row:
    """Run *prop* of *instance* (files under *folder*), inline if its properties file
    does not parse (:func:`parse_error`, asked once per file and kept in *unreadable*);
    with *exact*, in exact arithmetic."""
    model = f"{instance.family}/{instance.model}"
    props = f"{instance.family}/{instance.props}"
    base = [sys.executable, "-m", "veribattery", "prism", model]
    tail = ["--json", "--max-states", str(cap), *(["--exact"] if exact else [])]
    if props not in unreadable:
        unreadable[props] = parse_error(props, folder, timeout)
    if unreadable[props] is None:
        consts = [arg for k, v in instance.constants.items()
                  for arg in ("--const", f"{k}={literal(v)}")]
        command = [*base, "--props", props, "--property", prop, *consts, *tail]
        return outcome_row(instance, prop, command, run_process(command, folder, timeout),
                           inline=False)
    text = (folder / props).read_text(encoding="utf-8-sig")
    own = {k: v for k, v in instance.constants.items() if k in undefined_constants(text)}
    consts = [arg for k, v in instance.constants.items() if k not in own
              for arg in ("--const", f"{k}={literal(v)}")]
    command = [*base, "--property", substituted(named_properties(text)[prop], own), *consts,
               *tail]
    return outcome_row(instance, prop, command, run_process(command, folder, timeout),
                       inline=True)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _states_cell(row: Row) -> str:
    theirs = ", ".join(f"{number} ({note})" for number, note in row.instance.states)
    ours = "-" if row.states is None else str(row.states)
    if row.stopped:  # built up to where the property is decided: fewer, as Storm's
        return f"{ours} ({row.stopped} unexpanded) / {theirs}"
    if row.states is not None and row.states not in {n for n, _ in row.instance.states}:
        logged = [f"{tool} run: {n}" for tool, n in row.instance.logged_states.items()
                  if n == row.states]
        ours = f"**{ours}**"
        theirs += f"; {logged[0]}" if logged else ""
    return f"{ours} / {theirs}"


def _value_cell(row: Row) -> str:
    if row.outcome in ("refused", "error"):
        return f"{row.outcome}: `{_cell(row.message.removeprefix('error: '))}`"
    if row.outcome == "timeout":
        return "-"
    text = show(row.value)
    if row.bounds:
        text += f" [{show(row.bounds[0])}, {show(row.bounds[1])}]"
    return text


def _agree_cell(row: Row) -> str:
    return f"**{row.outcome}**" if row.outcome in FAILURES else row.outcome


def table_row(row: Row) -> str:
    """One Markdown table row."""
    reference = row.reference
    ref_cell = (f"{show(reference_value(reference.value))} ({reference.tool})"
                if reference else "-")
    prop = f"{row.prop} (inline)" if row.inline else row.prop
    return (f"| {row.instance.family} | {row.instance.label} | {prop} | {_states_cell(row)} "
            f"| {_value_cell(row)} | {ref_cell} | {_agree_cell(row)} | {row.wall_s:.1f} |")


def counts(rows: list[Row]) -> dict[str, int]:
    """How many rows of each outcome."""
    names = {"yes": "agree", "NO": "mismatch", "refused": "refused", "error": "errors",
             "timeout": "timeouts", "no reference": "without reference"}
    tally = dict.fromkeys(names.values(), 0)
    for row in rows:
        tally[names[row.outcome]] += 1
    return tally


def _shown(command: list[str]) -> str:
    return shlex.join(["python", *command[1:]])


def write(out: Path, kind: str, rows: list[Row], settings: str,
          unreadable: dict[str, str | None]) -> None:
    """The whole report: header, table, then the problems, the inline files, the warnings."""
    tally = ", ".join(f"{n} {name}" for name, n in counts(rows).items()
                      if n or name != "without reference")
    exactly = sum(row.exactly for row in rows)
    if exactly:
        tally += (f"; {exactly} of them against an exact result, fraction for fraction "
                  f"({sum(row.exactly and row.outcome == 'yes' for row in rows)} equal)")
    lines = [
        f"# veribattery on the PRISM-language {TITLES[kind]} of QVBS\n",
        "Generated by `bench/bench_qvbench_mdp.py` (do not edit by hand). " + settings,
        f"\n**{len(rows)} properties: {tally}.**\n",
        "States: ours / index.json's (the tool that counted; **bold**: ours differs, then a "
        "`results/` run that counted as many, if any; \"(N unexpanded)\": the states "
        "built when exploration stops where the property is decided, as Storm's does, N of "
        "them left unexpanded). Our value with its certified "
        "interval; the reference is an exact result where QVBS has one, else Storm's, else "
        "any. \"(inline)\": the properties file has a line veribattery cannot parse, so the "
        "property's text was passed with `--property TEXT`. Paths are relative to "
        f"`benchmarks/{kind}`.\n",
        "| family | instance | property | states (ours / QVBS) | our value [interval] "
        "| reference (tool) | agree | wall s |",
        "|---|---|---|---|---|---|---|---|",
        *(table_row(row) for row in rows),
    ]
    problems = [row for row in rows if row.outcome in FAILURES]
    if problems:
        lines.append("\n## Mismatches, errors and timeouts\n")
        for row in problems:
            tail = "\n".join(row.stderr.strip().splitlines()[-15:])
            lines += [f"- {row.instance.family} {row.instance.label} `{row.prop}`: "
                      f"{row.outcome} ({row.wall_s:.1f} s)", "",
                      f"  ```\n  {_shown(row.command)}\n  ```"]
            if tail:
                lines.append("  ```\n" + "\n".join(f"  {t}" for t in tail.splitlines())
                             + "\n  ```")
    failed = {props: line for props, line in unreadable.items() if line is not None}
    if failed:
        lines.append("\n## Properties files veribattery cannot parse\n")
        lines += [f"- `{props}`: `{_cell(line)}`" for props, line in failed.items()]
    warned = [row for row in rows if row.warnings]
    if warned:
        lines.append("\n## Warnings\n")
        lines += [f"- {row.instance.family} {row.instance.label} `{row.prop}`: "
                  + "; ".join(f"`{_cell(w)}`" for w in row.warnings) for row in warned]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")


def materialise(source: GitFolder, instance: Instance, folder: Path) -> str:
    """Write *instance*'s model and properties files under *folder*; the properties' text."""
    for name in (instance.model, instance.props):
        path = folder / instance.family / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(source.read(f"{instance.family}/{name}"))
    return (folder / instance.family / instance.props).read_text(encoding="utf-8-sig")


def progress(number: int, row: Row) -> None:
    """Print *row* as a progress line, and a traceback's command and stderr loudly."""
    reference = show(reference_value(row.reference.value)) if row.reference else "-"
    print(f"[{number}] {row.instance.family} {row.instance.label} {row.prop}"
          f"{' (inline)' if row.inline else ''}: "
          f"{'' if row.message else row.outcome + ' '}{_value_cell(row)} vs {reference} "
          f"({row.wall_s:.1f} s)", flush=True)
    if row.outcome == "error" or "Traceback" in row.stderr:
        print(f"!!! {row.outcome.upper()}: {_shown(row.command)}\n{row.stderr.rstrip()}",
              file=sys.stderr, flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, required=True,
                        help="QVBS: a checkout (holding benchmarks/) or a bare git dir")
    parser.add_argument("--type", choices=tuple(FAMILIES), default="mdp", dest="kind",
                        help="the model type: benchmarks/mdp or benchmarks/dtmc")
    parser.add_argument("--only", default="", help="families whose name contains this")
    parser.add_argument("--max-states", type=int, default=1_000_000,
                        help="largest instance taken, by index.json's state count")
    parser.add_argument("--per-family", type=int, default=4, help="instances per family")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds per process")
    parser.add_argument("--exact", action="store_true",
                        help="check in exact arithmetic; exact references met exactly")
    parser.add_argument("--out", type=Path, help="the report (default: "
                        "docs/_bench/qvbench_TYPE.md, qvbench_TYPE_exact.md with --exact)")
    args = parser.parse_args()
    byte_compile_sources()
    sys.set_int_max_str_digits(0)  # (oscillators' index.json has integers of 6,000 digits)
    source = GitFolder(args.root.expanduser(), f"benchmarks/{args.kind}")
    mode = "_exact" if args.exact else ""
    out = args.out or ROOT / f"docs/_bench/qvbench_{args.kind}{mode}.md"
    cap = BUILD_CAP_FACTOR * args.max_states
    start = time.perf_counter()
    families = f"the families whose name contains `{args.only}`" if args.only else "all families"
    header = (f"veribattery at commit {tree_commit()} (`python -m veribattery prism ... "
              f"--json{' --exact' if args.exact else ''}`, one property per fresh process, "
              f"timeout {args.timeout:.0f} s, "
              f"`--max-states {cap}`) on QVBS commit `{source.commit()}`, {families}: per "
              f"family the {args.per_family} smallest instances with at most "
              f"{args.max_states} states in index.json and a recorded result. "
              f"Run {datetime.now(UTC):%Y-%m-%d %H:%M} UTC")
    rows: list[Row] = []
    unreadable: dict[str, str | None] = {}

    def save(finished: bool) -> None:
        took = f"{time.perf_counter() - start:.0f} s {'in all' if finished else 'so far'}"
        exact = " (with --exact, exact references as fractions)" if args.exact else ""
        write(out, args.kind, rows, f"{header}, {took}. Agreement: relative tolerance 1e-6 "
              f"(absolute 1e-9 near 0), truth values exactly{exact}.", unreadable)

    with tempfile.TemporaryDirectory() as tmp:
        for family in (f for f in FAMILIES[args.kind] if args.only in f):
            try:
                found = family_instances(source, family)
            except FileNotFoundError as missing:
                print(f"{family}: skipped, no {missing.filename}", flush=True)
                continue
            for instance in select(found, args.max_states, args.per_family):
                try:
                    props_text = materialise(source, instance, Path(tmp))
                except FileNotFoundError as missing:  # (a snapshot may leave out large files)
                    print(f"{family} {instance.label}: skipped, no {missing.filename}",
                          flush=True)
                    continue
                for prop in named_properties(props_text):
                    rows.append(check(instance, prop, Path(tmp), args.timeout, cap, unreadable,
                                      exact=args.exact))
                    progress(len(rows), rows[-1])
                    save(finished=False)
    if rows:
        save(finished=True)
    tally = counts(rows)
    print(", ".join(f"{n} {name}" for name, n in tally.items())
          + f"; {time.perf_counter() - start:.0f} s")
    if tally["mismatch"] or tally["errors"] or tally["timeouts"]:
        sys.exit(1)


if __name__ == "__main__":
    main()
