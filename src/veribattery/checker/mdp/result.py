"""What an MDP kernel returns: certified values per state and an optimal strategy."""

from __future__ import annotations

from dataclasses import dataclass

from veribattery._types import FloatArray
from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.mdp.strategy import StepStrategy, Strategy

__all__ = ["MdpResult"]


@dataclass(frozen=True, slots=True)
class MdpResult:
    """Optimal values with certified enclosures, and a strategy that attains them.

    :param bounds: per state, the optimal value inside ``[lower, upper]`` (certified for
        the model as built; ``docs/mdp-numerics.md``).
    :param strategy: an optimal strategy (memoryless for unbounded objectives,
        step-dependent for step-bounded ones).
    """

    bounds: Bounds
    strategy: Strategy | StepStrategy

    @property
    def values(self) -> FloatArray:
        """The point value of each state."""
        return self.bounds.value

    @property
    def lower(self) -> FloatArray:
        """Certified lower bounds."""
        return self.bounds.lower

    @property
    def upper(self) -> FloatArray:
        """Certified upper bounds."""
        return self.bounds.upper
