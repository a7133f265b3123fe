"""The checker package exports exactly its public API."""

from __future__ import annotations

import veribattery.checker as checker


def test_all_is_the_public_api() -> None:
    assert sorted(checker.__all__) == ["CheckResult", "Keep", "UndecidedResult", "Workspace",
                                       "check", "state_set", "values"]
    for name in checker.__all__:
        assert getattr(checker, name) is not None
