"""PCTL model checking of DTMCs: formula recursion over numeric kernels.

The results are imported with the package; the checker itself (:func:`check`, the
formula recursion and its kernels) and :class:`Workspace` when first read, so that an
MDP's check, which shares the results and the formula leaves only, does not import them.
"""

from __future__ import annotations

import importlib
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from veribattery.checker.result import CheckResult, Keep, UndecidedResult

if TYPE_CHECKING:
    from veribattery.checker.api import check, state_set, values
    from veribattery.checker.workspace import Workspace

_EXPORTS = MappingProxyType({
    "veribattery.checker.api": ("check", "state_set", "values"),
    "veribattery.checker.workspace": ("Workspace",),
})
# read-only: the checker keeps no mutable module state (tests/checker/test_workspace.py)
_HOME = MappingProxyType(
    {name: module for module, names in _EXPORTS.items() for name in names})


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'veribattery.checker' has no attribute {name!r}")
    return getattr(importlib.import_module(_HOME[name]), name)


__all__ = ["CheckResult", "Keep", "UndecidedResult", "Workspace", "check", "state_set", "values"]
