"""PCTL model checking of DTMCs: formula recursion over numeric kernels."""

from veribattery.checker.api import check
from veribattery.checker.pctl import state_set, values
from veribattery.checker.result import CheckResult

__all__ = ["CheckResult", "check", "state_set", "values"]
