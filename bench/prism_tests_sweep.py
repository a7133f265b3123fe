"""Every DTMC and MDP ``// RESULT:`` of a PRISM checkout's prism-tests, beyond the peer suites.

    python bench/prism_tests_sweep.py --prism PRISM_CHECKOUT [--peer-tests DIR] [-j 2]
        [--exact] [--out FILE.md]

The peer suites (``../shared/peer-tests``) hold a subset of PRISM's regression tests;
this runs the rest of them (models of type ``dtmc``/``mdp``, or none: PRISM's MDP), each
property with a ``RESULT`` annotation and the constants it names (and a single-valued
``-const`` of its ``.args`` file), through the suites' own harness
(``prism_suite.py``, the same comparison), and sorts what fails by cause. ``--exact``
runs ``veribattery prism --exact`` on the entries whose ``.args`` ask PRISM for
``-exact``. Entries whose ``.args`` change what a property means (``-fair``,
``-noprobchecks``, a model type override, ``-param``) are left out. A PRISM checkout: ``git clone https://github.com/prismmodelchecker/prism``
(the suites were taken at 9486c774).
"""

from __future__ import annotations

import argparse
import itertools
import json
import re
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path
from types import ModuleType
from typing import Any

from compare_values import load_harness
from trees import default_peer_tests

#: The veribattery command of this environment (``make setup``'s virtualenv).
CLI = Path(sys.executable).with_name("veribattery")

#: The model keywords PRISM reads as a DTMC or an MDP (none at all: an MDP).
KINDS = {"dtmc": "dtmc", "probabilistic": "dtmc", "mdp": "mdp", "nondeterministic": "mdp"}
OTHER_KINDS = {"ctmc", "stochastic", "pta", "smg", "pomdp", "popta", "ctmdp", "csg", "tsg",
               "idtmc", "imdp", "lts", "ipomdp"}
MODEL_SUFFIXES = (".pm", ".nm", ".prism")
SUITES = ("prism", "prism-examples", "prism-extended", "prism-mdp")
#: PRISM options that change what a property means; entries run with them are left out.
ENGINE_OPTIONS = frozenset({"-fair", "-noprobchecks", "-ctmc", "-dtmc", "-mdp", "-param"})
#: Why an entry fails, by the text of its error (the first that matches).
CAUSES = (
    ("LTL inside multi(...) (not supported)", "multi(...) takes P objectives"),
    ("interval model (not supported)", "interval probability"),
    ("parametric constant (not supported)", "undefined constant"),
)


def model_kind(text: str) -> str | None:
    """``dtmc``/``mdp`` as PRISM reads the model's type keyword, None for another type."""
    for word in re.findall(r"[A-Za-z_]\w*", re.sub(r"//[^\n]*", "", text)):
        if word in KINDS:
            return KINDS[word]
        if word in OTHER_KINDS:
            return None
        if word in ("module", "const", "global", "formula", "label", "rewards", "init"):
            break
    return "mdp"


def args_lines(props: Path) -> list[str]:
    """The run configurations of *props*'s ``.args`` file (one per line)."""
    path = props.with_name(props.name + ".args")
    if not path.is_file():
        return []
    lines = (line.split("#")[0].strip() for line in path.read_text().splitlines())
    return [re.sub(r"(^|\s)--(?=\w)", r"\1-", line) for line in lines if line]  # --x: -x


def single_constants(line: str) -> dict[str, str]:
    """The single-valued ``-const`` assignments of one ``.args`` line."""
    found: dict[str, str] = {}
    tokens = line.split()
    for option, value in itertools.pairwise(tokens):
        if option == "-const":
            for part in value.split(","):
                name, _, given = part.partition("=")
                if given and ":" not in given:
                    found[name] = given
    return found


#: An entry's identity: model, properties file, property index, constants.
Key = tuple[str, str, int, tuple[tuple[str, str], ...]]
Entry = dict[str, Any]


def peer_keys(peer_tests: Path) -> set[Key]:
    """The entries the peer suites already hold."""
    keys: set[Key] = set()
    for suite in SUITES:
        for entry in json.loads((peer_tests / suite / "manifest.json").read_text())["entries"]:
            keys.add((entry["model"], entry["props"], entry["property_index"],
                      tuple(sorted((entry.get("constants") or {}).items()))))
    return keys


def entries(harness: ModuleType, root: Path, known: set[Key], exact: bool) -> list[Entry]:
    """The manifest entries of prism-tests under *root* (paths relative to *root*)."""
    found: list[Entry] = []
    for model in sorted(root.glob("prism-tests/**/*")):
        if model.suffix not in MODEL_SUFFIXES:
            continue
        if model_kind(model.read_text(errors="replace")) is None:
            continue
        for props in sorted(model.parent.glob(model.name + "*.props")):
            lines = args_lines(props)
            if exact != any("-exact" in line.split() for line in lines):
                continue
            if lines and ENGINE_OPTIONS & set(lines[0].split()):
                continue
            given = single_constants(lines[0]) if lines else {}
            text = props.read_text(errors="replace")
            defined = defined_constants(model.read_text(errors="replace") + "\n" + text)
            for statement in harness.split_statements(text):
                if statement["kind"] == "property":
                    found += _entries_of(harness, root, model, props, statement,
                                         (given, defined), known)
    return found


def defined_constants(text: str) -> set[str]:
    """The constants *text* gives a value (a ``RESULT (c=v)`` naming one only documents it)."""
    return set(re.findall(r"\bconst\s+(?:int|double|bool)?\s*(\w+)\s*=", text))


def _entries_of(harness: ModuleType, root: Path, model: Path, props: Path, statement: Entry,
                constants_of: tuple[dict[str, str], set[str]], known: set[Key]) -> list[Entry]:
    given, defined = constants_of
    out = []
    for named, expected_text in harness.result_specs(statement["comment"]):
        if named is None:
            continue
        constants = {k: v for k, v in {**given, **named}.items() if k not in defined}
        key: Key = (str(model.relative_to(root)), str(props.relative_to(root)), statement["index"],
               tuple(sorted(constants.items())))
        error = expected_text.lower().startswith("error")
        expected = "error" if error else harness.parse_value(expected_text)
        if key in known or expected is None:
            continue  # in a peer suite, or a result the harness cannot compare (p, ?)
        out.append({"id": f"{key[1]}#{key[2]}{constants or ''}", "model": key[0],
                    "props": key[1], "property_index": key[2], "property": statement["text"],
                    "constants": constants, "expected": expected,
                    "expected_text": expected_text})
    return out


def cause(line: str) -> str:
    """The cause of one ``FAIL`` line of the harness."""
    for name, text in CAUSES:
        if text in line:
            return name
    return "other"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--prism", type=Path, required=True, help="a PRISM checkout")
    parser.add_argument("--peer-tests", type=Path, default=default_peer_tests())
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("--exact", action="store_true",
                        help="the entries whose .args ask for -exact, with --exact")
    parser.add_argument("--out", type=Path, help="write the summary here too (markdown)")
    args = parser.parse_args()
    harness = load_harness(args.peer_tests)
    found = entries(harness, args.prism, peer_keys(args.peer_tests), args.exact)
    with tempfile.TemporaryDirectory() as folder:
        manifest = Path(folder) / "manifest.json"
        manifest.write_text(json.dumps({"format": "prism-dtmc-suite/1", "entries": found}))
        command = f"{CLI} prism" + (" --exact" if args.exact else "")
        run = subprocess.run(
            [sys.executable, str(args.peer_tests / "prism_suite.py"), str(manifest),
             "--root", str(args.prism), "--cmd", command, "-j", str(args.jobs),
             "--timeout", "300"], capture_output=True, text=True, check=False)
    failed = [line for line in run.stdout.splitlines() if line.startswith("FAIL")]
    causes = Counter(cause(line) for line in failed)
    summary = [f"{len(found)} entries beyond the peer suites"
               f"{' (-exact ones, with --exact)' if args.exact else ''}: "
               f"{run.stdout.strip().splitlines()[-1]}", ""]
    summary += [f"- {name}: {count}" for name, count in causes.most_common()]
    summary += ["", "Other failures:", ""] + [
        f"    {line[:300]}" for line in failed if cause(line) == "other"]
    text = "\n".join(summary)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
