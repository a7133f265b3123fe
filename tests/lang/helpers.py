"""Shared helpers for the PRISM-language tests."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from tests.conftest import PEER_TESTS
from tests.peer_manifests import manifest, missing
from veribattery.lang.nodes import FlatModel, Model, PropertiesFile, Property

#: The nodes whose repr is short (names and texts, for a notebook); :func:`tree` spells
#: them out.
_SHORT_REPRS = (FlatModel, Model, PropertiesFile, Property)


def tree(node: object) -> str:
    """Every field of *node*, spans included: the dataclasses' own repr, which the short
    reprs of a model, a properties file and a property leave out (the fast parser must
    build what lark builds, every position too, and spans are not compared by ``==``)."""
    if isinstance(node, _SHORT_REPRS):
        inner = ", ".join(f"{f.name}={tree(getattr(node, f.name))}"
                          for f in dataclasses.fields(node))
        return f"{type(node).__name__}({inner})"
    if isinstance(node, tuple):
        return "(" + "".join(f"{tree(item)}, " for item in node) + ")"
    return repr(node)


PEER = PEER_TESTS
SUITES = ("prism", "prism-examples")
#: The suites of DTMC models, whose every file the front end must read. ``prism-mdp``
#: (Markov decision processes) is tested end to end by tests/test_peer_mdp.py.
DTMC_SUITES = ("prism", "prism-examples", "prism-extended")


def manifest_entries() -> list[Any]:
    """(suite root, entry) for every entry of both peer manifests; a missing manifest is
    one ``(root, None)`` case, which the test must fail (:func:`fail_missing`)."""
    entries: list[Any] = []
    for suite in SUITES:
        data = manifest(suite)
        if data is None:
            entries.append(missing(suite, PEER / suite, None))
            continue
        entries += [pytest.param(PEER / suite, e, id=e["id"]) for e in data["entries"]]
    return entries


def peer_files(*suffixes: str) -> list[Any]:
    """Every peer-suite file with one of *suffixes*, with its relative path as the id
    (without ../shared, one case that skips and says why)."""
    if not PEER.exists():
        return [pytest.param(None, id="peer-suites-absent", marks=pytest.mark.skip(
            reason=f"peer suites not found at {PEER} (../shared is absent)"))]
    files = sorted(p for suite in DTMC_SUITES for p in (PEER / suite).rglob("*")
                   if p.suffix in suffixes)
    return [pytest.param(p, id=str(p.relative_to(PEER))) for p in files]


def expression_depth(expr: Any) -> int:
    """How deep *expr*'s tree is (measured without recursion, as it may be very deep)."""
    from veribattery.lang.expressions import children

    deepest, stack = 0, [(expr, 1)]
    while stack:
        node, level = stack.pop()
        deepest = max(deepest, level)
        stack.extend((child, level + 1) for child in children(node))
    return deepest


MINI = """dtmc
const int N = 3;
module m
  x : [0..N] init 0;
  [a] x<N -> 0.5:(x'=x+1) + 0.5:(x'=x);
endmodule
"""
