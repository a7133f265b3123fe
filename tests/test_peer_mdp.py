"""The PRISM MDP peer suite (``prism-mdp``) through the `veribattery prism` CLI contract.

Every entry passes: this counts the entries that pass and holds that count at
:data:`~tests.peer_manifests.MDP_PASSING` (all 163) or above. A value entry passes
with exit status 0, or with 2 where the answer is one the CLI reports as bad input
after showing it (an infeasible ``multi``: NaN).
"""

from __future__ import annotations

import math
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
    expected = harness.parse_value(entry["expected"])
    if result.exit_code != 0 and not _ill_posed(expected, result.exit_code, result.stderr):
        return False
    found, got, _ = harness.extract_value(result.stdout)
    if not found:
        return False
    return bool(harness.values_match(expected, got, entry.get("rtol", 1e-6), 1e-12))


def _ill_posed(expected: Any, exit_code: int, stderr: str) -> bool:
    """An answer PRISM gives that the CLI shows and then reports as bad input (an
    infeasible ``multi``'s NaN, an unreachable ``Rmin`` target's Infinity): exit 2 with
    one ``error:`` line naming the property."""
    special = isinstance(expected, float) and not math.isfinite(expected)
    errors = [line for line in stderr.splitlines() if line.startswith("error:")]
    return special and exit_code == 2 and len(errors) == 1


def test_mdp_suite_passes_at_least_the_floor() -> None:
    data = manifest("prism-mdp")
    if data is None:
        fail_missing("prism-mdp")
    harness = peer_harness()
    passed = sum(_passes(harness, entry) for entry in data["entries"])
    assert_enough(passed, MDP_PASSING, "prism-mdp entries passing")
