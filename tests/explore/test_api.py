"""The public API of veribattery.explore."""

from __future__ import annotations

import veribattery.explore as explore


def test_all_is_exact() -> None:
    assert sorted(explore.__all__) == [
        "DTMC",
        "RewardVectors",
        "build_compact_dtmc",
        "build_dtmc",
        "check_update_ranges_over_domain",
        "compile_expr",
    ]
    for name in explore.__all__:
        assert hasattr(explore, name)
