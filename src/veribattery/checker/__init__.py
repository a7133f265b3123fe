"""PCTL model checking of DTMCs: formula recursion over numeric kernels.

The results are imported with the package; the checker itself (:func:`check`, the
formula recursion and its kernels) and :class:`Workspace` when first read, so that an
MDP's check, which shares the results and the formula leaves only, does not import them.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import TYPE_CHECKING

from veribattery._lazy import lazy_exports
from veribattery.checker.result import CheckResult, Keep, UndecidedResult

if TYPE_CHECKING:
    from veribattery.checker.api import check, state_set, values
    from veribattery.checker.workspace import Workspace

_EXPORTS = MappingProxyType({
    "veribattery.checker.api": ("check", "state_set", "values"),
    "veribattery.checker.workspace": ("Workspace",),
})
__getattr__ = lazy_exports(__name__, _EXPORTS)


__all__ = ["CheckResult", "Keep", "UndecidedResult", "Workspace", "check", "state_set", "values"]
