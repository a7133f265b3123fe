"""Shared helpers for the PRISM-language tests."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

PEER = Path("/work/shared/peer-tests")
SUITES = ("prism", "prism-examples")


def manifest_entries() -> list[Any]:
    """(suite root, entry) for every entry of both peer manifests (empty if absent)."""
    entries: list[Any] = []
    for suite in SUITES:
        path = PEER / suite / "manifest.json"
        if path.exists():
            data = json.loads(path.read_text(encoding="utf-8"))
            entries += [pytest.param(PEER / suite, e, id=e["id"]) for e in data["entries"]]
    return entries


def peer_files(*suffixes: str) -> list[Any]:
    """Every peer-suite file with one of *suffixes*, with its relative path as the id."""
    if not PEER.exists():
        return []
    files = sorted(p for p in PEER.rglob("*") if p.suffix in suffixes)
    return [pytest.param(p, id=str(p.relative_to(PEER))) for p in files]


MINI = """dtmc
const int N = 3;
module m
  x : [0..N] init 0;
  [a] x<N -> 0.5:(x'=x+1) + 0.5:(x'=x);
endmodule
"""
