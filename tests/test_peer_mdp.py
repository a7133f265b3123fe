"""The PRISM MDP peer suite (``prism-mdp``) through the `veribattery prism` CLI contract.

Every entry passes: this counts the entries that pass and holds that count at
:data:`~tests.peer_manifests.MDP_PASSING` (all 163) or above.
"""

from __future__ import annotations

from typing import Any

from click.testing import CliRunner

from tests.conftest import PEER_TESTS, peer_harness
from tests.peer_manifests import MDP_PASSING, assert_enough, fail_missing, manifest
from veribattery.cli import cli


def _passes(harness: Any, entry: dict[str, Any]) -> bool:
    argv = harness.entry_argv(entry, str(PEER_TESTS / "prism-mdp"), [])
    result = CliRunner().invoke(cli, ["prism", *argv])
    if harness.expects_error(entry):
        passed, _ = harness.error_outcome(result.exit_code, result.stdout, result.stderr)
        return bool(passed)
    if result.exit_code != 0:
        return False
    found, got, _ = harness.extract_value(result.stdout)
    if not found:
        return False
    expected = harness.parse_value(entry["expected"])
    return bool(harness.values_match(expected, got, entry.get("rtol", 1e-6), 1e-12))


def test_mdp_suite_passes_at_least_the_floor() -> None:
    data = manifest("prism-mdp")
    if data is None:
        fail_missing("prism-mdp")
    harness = peer_harness()
    passed = sum(_passes(harness, entry) for entry in data["entries"])
    assert_enough(passed, MDP_PASSING, "prism-mdp entries passing")
