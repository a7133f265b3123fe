"""The peer suites' manifests as test parameters, so that no suite can drop out unseen.

Without ../shared every peer-suite test skips, saying so (:func:`require_shared`).
With it, a suite whose manifest is missing stands in the parametrisation as one
``<suite>-manifest-missing`` case that fails, and the corpus-driven tests assert
that they found at least :data:`FLOORS` cases: an empty or truncated manifest
cannot pass as "nothing to check".
"""

from __future__ import annotations

import json
from typing import Any, NoReturn

import pytest

from tests.conftest import PEER_TESTS, require_shared

#: How many entries each manifest lists (counted 2026-11-26); a floor, not an exact count.
FLOORS = {"prism": 144, "prism-examples": 120, "prism-extended": 204}
#: prism-mdp entries that pass (of 163): all of them (an infeasible numerical
#: multi(...) query is NaN with a warning naming the property, as PRISM reports it).
MDP_PASSING = 163


def manifest(suite: str) -> dict[str, Any] | None:
    """*suite*'s manifest, or None when its file is not there."""
    path = PEER_TESTS / suite / "manifest.json"
    if not path.is_file():
        return None
    data: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    return data


def missing(suite: str, *values: object) -> Any:
    """The one parameter set that stands for *suite* when its manifest is missing."""
    return pytest.param(*values, id=f"{suite}-manifest-missing")


def fail_missing(suite: str) -> NoReturn:
    """Skip visibly without ../shared; with it, fail: the suite's manifest must be there."""
    require_shared()
    pytest.fail(f"{PEER_TESTS / suite / 'manifest.json'} is missing: "
                f"the peer suite {suite!r} was not run")


def assert_enough(found: int, floor: int, what: str) -> None:
    """At least *floor* cases of *what*, once ../shared is there (else a visible skip)."""
    require_shared()
    assert found >= floor, (f"only {found} {what} (at least {floor} expected): "
                            "a manifest is missing or shrank")
