"""Checks influence each other only through a workspace they share (checker.Workspace).

The checker keeps its graph searches, linear systems and plans in the workspace its
caller passes; a check given another workspace, or none, starts from nothing. The
counts are of the restricted systems built (``systems_built``, tests/checker/conftest.py).
"""

from __future__ import annotations

import importlib
import pkgutil
import weakref
from collections import OrderedDict
from fractions import Fraction

import pytest

import veribattery.checker as checker
from tests.checker.chains import gamblers_ruin
from veribattery.checker import Workspace, check
from veribattery.checker.result import CheckResult
from veribattery.lang import parse_property

RUIN = gamblers_ruin(20, 0.4)  # fortune 1 of 0..20: 19 unknown states
WIN = parse_property('P=? [ F "win" ]')
STEPS = parse_property('R{"steps"}=? [ F "end" ]')


def _win_from_one() -> Fraction:
    """P(reach 20 before 0) from 1 with p = 2/5: (1 - r) / (1 - r^20), r = q/p = 3/2."""
    r = Fraction(3, 2)
    return (1 - r) / (1 - r**20)


def _holds(result: CheckResult, exact: Fraction) -> bool:
    assert result.lower is not None and result.upper is not None
    return Fraction(result.lower) <= exact <= Fraction(result.upper)


def test_a_second_workspace_starts_empty_and_builds_its_own(systems_built: list[int]) -> None:
    first, second = Workspace(), Workspace()
    assert first.empty and second.empty
    a = check(RUIN, WIN, workspace=first)
    assert not first.empty
    assert second.empty  # the first check left nothing where the second looks
    b = check(RUIN, WIN, workspace=second)
    assert systems_built == [19, 19]
    assert (a.value, a.lower, a.upper) == (b.value, b.lower, b.upper)
    assert _holds(a, _win_from_one())


def test_a_shared_workspace_serves_the_next_check(systems_built: list[int]) -> None:
    shared = Workspace()
    a = check(RUIN, WIN, workspace=shared)
    b = check(RUIN, WIN, workspace=shared)
    assert systems_built == [19]  # the second is answered from the first's result
    assert (a.value, a.lower, a.upper) == (b.value, b.lower, b.upper)


def test_checks_without_a_workspace_share_nothing(systems_built: list[int]) -> None:
    a = check(RUIN, WIN)
    b = check(RUIN, WIN)
    assert systems_built == [19, 19]
    assert a.value == b.value and _holds(b, _win_from_one())


def test_prepare_builds_in_its_own_workspace_only(systems_built: list[int]) -> None:
    prepared, other = Workspace(), Workspace()
    prepared.prepare(RUIN, [WIN.formula, STEPS.formula])
    assert systems_built == [19]  # R's system, which P=? [ F "win" ] is solved on
    check(RUIN, WIN, workspace=prepared)
    check(RUIN, STEPS, workspace=prepared)
    assert systems_built == [19]
    assert other.empty
    check(RUIN, WIN, workspace=other)
    assert systems_built == [19, 19]


def test_a_dropped_workspace_frees_its_systems_while_the_chain_lives() -> None:
    workspace = Workspace()
    check(RUIN, STEPS, workspace=workspace)
    system = next(iter(workspace.kernels.of(RUIN.transitions).systems.values()))
    solver = weakref.ref(system.factorization)
    del workspace, system
    assert solver() is None  # by reference counting: no cycle, no finalizer holds it


def _mutable_state(module: object) -> list[str]:
    """The module's globals that hold mutable data: containers other than tables of
    functions (operator tables)."""
    mutable = (list, set, dict, OrderedDict, bytearray, weakref.WeakSet,
               weakref.WeakKeyDictionary, weakref.WeakValueDictionary)
    found = []
    for name, value in vars(module).items():
        table = isinstance(value, dict) and all(callable(v) for v in value.values())
        if isinstance(value, mutable) and not table and not name.startswith("__"):
            found.append(name)
    return found


@pytest.mark.parametrize("name", [m.name for m in pkgutil.walk_packages(checker.__path__,
                                                                      "veribattery.checker.")])
def test_no_checker_module_keeps_state_or_trims_the_heap(name: str) -> None:
    module = importlib.import_module(name)
    assert _mutable_state(module) == []
    # Heap trimming is for stage boundaries (the pipeline), not inside the kernels.
    assert not {"trim_for", "trim_heap"} & vars(module).keys()
