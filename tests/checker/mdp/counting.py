"""Counting the strategy evaluations (sparse LU solves of a whole system) a solve makes."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from veribattery.checker.mdp import solve as solve_module
from veribattery.checker.mdp import topological


def counted_evaluations(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """A one-element list that counts the evaluations from now on."""
    calls = [0]
    evaluate: Callable[..., Any] = solve_module.evaluate

    def counting(*args: Any, **kwargs: Any) -> Any:
        calls[0] += 1
        return evaluate(*args, **kwargs)

    monkeypatch.setattr(solve_module, "evaluate", counting)
    monkeypatch.setattr(topological, "evaluate", counting)
    return calls
