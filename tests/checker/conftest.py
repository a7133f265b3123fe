"""Fixtures shared by the checker's tests."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from veribattery.checker import linalg
from veribattery.checker.kernels import systems

#: Replaces ``owner.name`` by a spy; returns, per call, whether it answered (not None).
SpyAnswers = Callable[[object, str], list[bool]]


@pytest.fixture
def quick_systems(monkeypatch: pytest.MonkeyPatch) -> SpyAnswers:
    """The quick certificates on every system (small ones included), and kept systems
    used whatever the share of their states a query has (a cost rule); returns a
    function that spies on a kernel's answers."""
    monkeypatch.setattr(systems, "QUICK_MIN_STATES", 1)
    monkeypatch.setattr(systems, "SUPERSET_SHARE", 0.0)

    def spy_on(owner: object, name: str) -> list[bool]:
        answered: list[bool] = []
        original = getattr(owner, name)

        def spy(*args):  # type: ignore[no-untyped-def]
            found = original(*args)
            answered.append(found is not None)
            return found

        monkeypatch.setattr(owner, name, spy)
        return answered

    return spy_on


@pytest.fixture
def systems_built(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """How many restricted systems the kernels build (sizes, in order)."""
    built: list[int] = []
    original = linalg.restricted_parts

    def counting(P, maybe, plans=None):  # type: ignore[no-untyped-def]
        built.append(int(maybe.sum()))
        return original(P, maybe, plans)

    monkeypatch.setattr(linalg, "restricted_parts", counting)
    yield built


@pytest.fixture
def gains_carried(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Spies on ``horizon.gained``: the rounds left at each try to carry ``C<=k``
    forward by its gain."""
    from veribattery.checker.certify import horizon

    carried: list[int] = []
    gained = horizon.gained

    def spy(*args):  # type: ignore[no-untyped-def]
        carried.append(int(args[2]))
        return gained(*args)

    monkeypatch.setattr(horizon, "gained", spy)
    return carried
