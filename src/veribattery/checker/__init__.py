"""PCTL model checking of DTMCs: formula recursion over numeric kernels."""

from veribattery.checker.api import check, state_set, values
from veribattery.checker.result import CheckResult, Keep, UndecidedResult
from veribattery.checker.workspace import Workspace

__all__ = ["CheckResult", "Keep", "UndecidedResult", "Workspace", "check", "state_set", "values"]
