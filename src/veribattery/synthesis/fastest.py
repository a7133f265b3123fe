"""The fastest strategy that is safe enough: ``multi(R{"mt"}min=? [ C ], P>=p [ F "success" ])``.

Where *p* is not below ``Pmax``'s certified interval the answer needs no programme
(:func:`fastest_near_pmax`); elsewhere it is one.

Each answer is a linear programme over occupation measures solved in floating point by
HiGHS (:func:`~veribattery.checker.mdp.multi_optimum`): *not* certified, good to about
HiGHS's feasibility tolerance (:data:`LP_TOLERANCE`). Such a strategy may need to
randomise. Its expected recharges are a second programme: the fewest recharges among
the strategies that meet *p* and are at most :data:`TIME_SLACK` (relative) slower than
the fastest.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

from veribattery.checker.mdp import MDP, Constraint, Reach, Total, multi_optimum
from veribattery.errors import OptionError
from veribattery.render import FastestQuestion
from veribattery.synthesis.model import Certified
from veribattery.synthesis.optimal import ChosenStrategy
from veribattery.synthesis.pareto import FrontPoint

__all__ = ["LP_TOLERANCE", "TIME_SLACK", "Fastest", "as_safe_as", "fastest",
           "fastest_near_pmax", "front", "required_at_least"]

#: HiGHS's primal feasibility tolerance: how far an LP answer may be off a bound.
LP_TOLERANCE = 1e-7
#: How much slower than the fastest a strategy may be in the recharges' programme.
TIME_SLACK = 1e-6


@dataclass(frozen=True, slots=True)
class Fastest:
    """The answer to one requirement on P(success).

    :ivar requirement: as written, e.g. ``p_success >= 0.99``.
    :ivar p: the least P(success) required (a strict ``>`` is read as ``>=``, as PRISM
        does).
    :ivar achievable: whether some strategy meets it (by the programme).
    :ivar exp_mission_time: the least expected mission time of one that does (None:
        none does).
    :ivar exp_recharges: the expected recharges of such a strategy (None: none does,
        or the second programme found none within :data:`TIME_SLACK`).
    :ivar certified: True when the answer comes from certified values rather than a
        linear programme: *p* above ``Pmax``'s certified interval (none meets it), or
        inside it (the safest-then-fastest strategy is the answer, to within that
        interval's width).
    """

    requirement: str
    p: float
    achievable: bool
    exp_mission_time: float | None
    exp_recharges: float | None
    certified: bool = False


def required_at_least(p: float | Fraction) -> FastestQuestion:
    """The requirement ``p_success >= p`` (``--require p``).

    :raises OptionError: when *p* is not a probability.
    """
    if not 0 <= p <= 1:  # NaN included
        raise OptionError(f"--require {p}: not a probability; give a number in [0, 1]")
    bound = Fraction(p).limit_denominator(10**12) if isinstance(p, float) else Fraction(p)
    return FastestQuestion("required", f"p_success >= {p}", ">=", bound)


def as_safe_as(p_success: float) -> FastestQuestion:
    """The requirement to be at least as safe as BS1, whose P(success) is *p_success*."""
    return FastestQuestion("bs1", f"p_success >= BS1's {p_success:.12g}", ">=",
                           Fraction(p_success))


def fastest_near_pmax(question: FastestQuestion, p_success_max: Certified,
                      safest: ChosenStrategy) -> Fastest | None:
    """The answer without a linear programme where *p* is not below ``Pmax``'s certified
    interval, else None.

    Above it, no strategy meets *p* (certified). Inside it, the strategies that meet *p*
    are those that attain ``Pmax`` (up to the interval's width), and the fastest of them
    is *safest*, the safest-then-fastest strategy, with its certified values.
    """
    p = float(question.bound)
    if p > p_success_max.upper:
        return Fastest(question.requirement, p, False, None, None, certified=True)
    if p >= p_success_max.lower:
        return Fastest(question.requirement, p, True, safest.exp_mission_time.value,
                       safest.exp_recharges.value, certified=True)
    return None


def fastest(mdp: MDP, question: FastestQuestion) -> Fastest:
    """The fastest strategy of *mdp* that meets *question* (its P(success) bound), by
    linear programmes."""
    p = float(question.bound)
    success = Reach(mdp.labels["success"])
    time = Total(mdp.reward("mt").per_choice(mdp))
    safe_enough = Constraint(success, ">=", p)
    answer = multi_optimum(mdp, time, "min", [safe_enough])
    if not answer.achievable or answer.value is None:
        return Fastest(question.requirement, p, False, None, None)
    recharges = multi_optimum(mdp, Total(mdp.reward("rc").per_choice(mdp)), "min", [
        safe_enough, Constraint(time, "<=", answer.value * (1 + TIME_SLACK) + TIME_SLACK)])
    return Fastest(question.requirement, p, True, answer.value, recharges.value)


def front(mdp: MDP, ps: Sequence[float]) -> tuple[FrontPoint, ...]:
    """The Pareto front at each required P(success) in *ps* that some strategy meets."""
    success = Reach(mdp.labels["success"])
    time = Total(mdp.reward("mt").per_choice(mdp))
    points = []
    for p in ps:
        answer = multi_optimum(mdp, time, "min", [Constraint(success, ">=", p)])
        if answer.achievable and answer.value is not None:
            points.append(FrontPoint(p, answer.value))
    return tuple(points)
