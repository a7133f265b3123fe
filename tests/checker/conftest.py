"""Fixtures shared by the checker's tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from veribattery.checker import linsolve


@pytest.fixture
def systems_built(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """How many restricted systems the kernels build (sizes, in order)."""
    built: list[int] = []
    original = linsolve.restricted_parts

    def counting(P, maybe):  # type: ignore[no-untyped-def]
        built.append(int(maybe.sum()))
        return original(P, maybe)

    monkeypatch.setattr(linsolve, "restricted_parts", counting)
    yield built
