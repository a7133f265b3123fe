"""State-space exploration: compile expressions, build the DTMC of a flat model."""

from veribattery.explore.build.builder import build_dtmc
from veribattery.explore.build.compact import build_compact_dtmc
from veribattery.explore.build.domain import check_update_ranges_over_domain
from veribattery.explore.compile.expr import compile_expr
from veribattery.explore.dtmc import DTMC, RewardVectors

__all__ = [
    "DTMC",
    "RewardVectors",
    "build_compact_dtmc",
    "build_dtmc",
    "check_update_ranges_over_domain",
    "compile_expr",
]
