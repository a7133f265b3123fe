"""check_update_ranges_over_domain: PRISM's whole-domain range check."""

from __future__ import annotations

import pytest

from tests.explore.models import command, flat_model, module, var
from veribattery.errors import ModelError, Span
from veribattery.explore import build_dtmc, check_update_ranges_over_domain


def test_unreachable_violation_is_found() -> None:
    # Reachable: x stays 0 (y never becomes 1). Over the domain, y=1 & x=3 -> x'=4.
    model = flat_model(
        [var("x", 0, 3), var("y", 0, 1)],
        [module("M", ["x", "y"], [command("y = 1", [("1", {"x": "x+1"})], line=5)])],
    )
    assert build_dtmc(model).num_states == 1
    with pytest.raises(
        ModelError,
        match=r"module M, command: update sets x to 4, outside its range 0\.\.3, "
        r"in state \(x=3, y=1\)",
    ) as info:
        check_update_ranges_over_domain(model)
    assert info.value.span == Span(5, 3, "test.pm")


def test_guarded_updates_pass() -> None:
    model = flat_model(
        [var("x", 0, 3), var("z", 0, 1000)],  # z is not mentioned: not enumerated
        [module("M", ["x"], [command("x < 3", [("0.5", {"x": "x+1"}), ("0.5", {})])])],
    )
    assert check_update_ranges_over_domain(model) == ()


def test_too_large_domains_are_reported_not_skipped_silently() -> None:
    model = flat_model(
        [var("x", 0, 9999), var("y", 0, 9999)],
        [module("M", ["x", "y"], [command("x < y", [("1", {"x": "x+1"})], line=2)])],
    )
    warnings = check_update_ranges_over_domain(model, max_combinations=1000)
    assert len(warnings) == 1
    assert "module M" in warnings[0] and "100000000 combinations" in warnings[0]


def test_synchronised_commands_are_checked_too() -> None:
    model = flat_model(
        [var("x", 0, 1, module="A"), var("y", 0, 1, module="B")],
        [
            module("A", ["x"], [command("true", [("1", {"x": "1"})], action="s")]),
            module("B", ["y"], [command("true", [("1", {"y": "y+1"})], action="s", line=8)]),
        ],
    )
    with pytest.raises(ModelError, match="module B, command \\[s\\]: update sets y to 2"):
        check_update_ranges_over_domain(model)
