"""The PRISM peer suites, every entry, through the `veribattery prism` CLI contract.

Each manifest entry is run in-process with click's CliRunner using the argument
list the suite's own harness (`prism_suite.py`) would pass, and judged by the
harness's own value extraction and tolerance, so passing here means passing
`prism_suite.py MANIFEST --cmd "veribattery prism"`. One test also runs the
harness itself against the installed console script.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from tests.conftest import PEER_TESTS, peer_harness, require_shared
from tests.peer_manifests import FLOORS, assert_enough, fail_missing, manifest, missing
from veribattery.cli import cli

SUITES = ("prism", "prism-examples", "prism-extended")


def _entries() -> list[Any]:
    params = []
    for suite in SUITES:
        data = manifest(suite)
        if data is None:
            params.append(missing(suite, suite, None))
            continue
        for entry in data["entries"]:
            params.append(pytest.param(suite, entry, id=f"{suite}:{entry['id']}"))
    return params


ENTRIES = _entries()


@pytest.mark.parametrize(("suite", "entry"), ENTRIES)
def test_peer_entry(suite: str, entry: dict[str, Any] | None) -> None:
    if entry is None:
        fail_missing(suite)
    harness = peer_harness()
    argv = harness.entry_argv(entry, str(PEER_TESTS / suite), [])
    result = CliRunner().invoke(cli, ["prism", *argv])
    if harness.expects_error(entry):
        passed, message = harness.error_outcome(result.exit_code, result.stdout, result.stderr)
        assert passed, message
        return
    assert result.exit_code == 0, result.output
    found, got, raw = harness.extract_value(result.stdout)
    assert found, result.output
    expected = harness.parse_value(entry["expected"])
    rtol = entry.get("rtol", 1e-6)
    assert harness.values_match(expected, got, rtol, 1e-12), (expected, raw)


@pytest.mark.parametrize("suite", SUITES)
def test_each_manifest_lists_its_entries(suite: str) -> None:
    """No suite runs fewer entries than its manifest listed when these tests were written."""
    count = sum(1 for p in ENTRIES if p.values[0] == suite and p.values[1] is not None)
    assert_enough(count, FLOORS[suite], f"{suite} entries")


def test_peer_entry_sizes() -> None:
    """The prism-examples manifest states, transitions and initial states, exactly (PRISM
    builds every state: so does ``--all-states``)."""
    require_shared()
    examples = json.loads((PEER_TESTS / "prism-examples" / "manifest.json").read_text())
    seen = set()
    for entry in examples["entries"]:
        key = (entry["model"], tuple(sorted(entry["constants"].items())))
        if key in seen:
            continue
        seen.add(key)
        argv = peer_harness().entry_argv(entry, str(PEER_TESTS / "prism-examples"), [])
        output = CliRunner().invoke(cli, ["prism", *argv, "--all-states"]).stdout
        model = json.loads(output)["model"]
        assert (model["states"], model["transitions"], model["initial_states"]) == (
            entry["states"], entry["transitions"], entry["initial_states"]
        ), entry["id"]
    assert_enough(len(seen), 24, "prism-examples (model, constants) pairs")


def test_harness_runs_the_console_script() -> None:
    """`prism_suite.py MANIFEST --cmd "veribattery prism"` passes on a slice of each suite."""
    require_shared()
    exe = shutil.which("veribattery") or str(Path(sys.executable).parent / "veribattery")
    # (suite, --filter, entries it selects: 17 and 28 when this was written)
    for suite, pattern, floor in (("prism", "dtmc_pctl", 17), ("prism-examples", "dice", 28)):
        proc = subprocess.run(
            [sys.executable, str(PEER_TESTS / "prism_suite.py"),
             str(PEER_TESTS / suite / "manifest.json"), "--cmd", f"{exe} prism",
             "--filter", pattern, "-j", "2"],
            capture_output=True, text=True, timeout=600, check=False,
        )
        assert proc.returncode == 0, proc.stdout + proc.stderr
        counts = re.fullmatch(r"(\d+) passed, 0 failed", proc.stdout.splitlines()[-1])
        assert counts is not None and int(counts[1]) >= floor, proc.stdout
