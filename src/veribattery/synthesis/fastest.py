"""The fastest strategy that is safe enough: ``multi(R{"mt"}min=? [ C ], P>=p [ F "success" ])``.

Where *p* is not below ``Pmax``'s certified interval the answer needs no search
(:func:`fastest_near_pmax`). Elsewhere it comes from the Pareto front of
(P(success), E[mission time]) by weighted sums
(:mod:`~veribattery.checker.mdp.multi_front`): a certified interval for the least
expected mission time, and the strategy that attains its upper end -- two deterministic
strategies, one of them chosen once at the start with a known probability. Its
expected recharges are that same mixed strategy's (certified too): the recharges of
the fastest strategy found, not the fewest among all the fastest.

Only where the front leaves the question open (a *p* so close to ``Pmax`` that the
safest strategy found cannot certainly meet it, below ``Pmax``'s certified interval)
is the answer a linear programme (HiGHS, not certified, :data:`LP_TOLERANCE`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction

from veribattery.checker.mdp import (
    MDP,
    CertifiedAnswer,
    Constraint,
    FrontSearch,
    Reach,
    Total,
    multi_optimum,
)
from veribattery.errors import OptionError
from veribattery.render import FastestQuestion
from veribattery.synthesis.model import Certified
from veribattery.synthesis.optimal import ChosenStrategy
from veribattery.synthesis.pareto import FrontPoint

__all__ = ["FRONT_TOLERANCE", "LP_TOLERANCE", "Fastest", "as_safe_as", "fastest",
           "fastest_near_pmax", "front", "mission_front", "required_at_least"]

#: HiGHS's primal feasibility tolerance: how far an LP answer may be off a bound.
LP_TOLERANCE = 1e-7
#: How far above the exact front the drawn one may lie, relative to the expected
#: mission time: the paper's baseline has vertices 1e-6 apart in P(success) (its exact
#: front needs hundreds of weighted optima); 1e-4 is 0.4 min in 3,900, finer than a
#: figure shows.
FRONT_TOLERANCE = 1e-4


@dataclass(frozen=True, slots=True)
class Fastest:
    """The answer to one requirement on P(success).

    :ivar requirement: as written, e.g. ``p_success >= 0.99``.
    :ivar p: the least P(success) required (a strict ``>`` is read as ``>=``, as PRISM
        does).
    :ivar achievable: whether some strategy meets it.
    :ivar exp_mission_time: the least expected mission time of one that does (None:
        none does): the point value inside *time_bounds*.
    :ivar exp_recharges: the expected recharges of the strategy found (None: none does,
        or a linear programme answered).
    :ivar certified: True when the answer comes from certified values rather than a
        linear programme.
    :ivar time_bounds: the certified interval of the least expected mission time
        (None: not from the front).
    :ivar recharges_bounds: the certified interval of the strategy's recharges.
    :ivar mixing: the probability with which the strategy found follows the safer of
        its two deterministic strategies (0: it is deterministic).
    :ivar solves: the weighted optima solved for the front so far.
    """

    requirement: str
    p: float
    achievable: bool
    exp_mission_time: float | None
    exp_recharges: float | None
    certified: bool = False
    time_bounds: tuple[float, float] | None = None
    recharges_bounds: tuple[float, float] | None = None
    mixing: float = 0.0
    solves: int = 0


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


def mission_front(mdp: MDP, on_solve: Callable[[int], None] | None = None) -> FrontSearch:
    """The front search of *mdp*: P(success) against E[mission time], E[recharges]
    carried along (one per synthesis run: its weighted optima are kept); *on_solve* is
    told the weighted solves made so far after each."""
    return FrontSearch(mdp, Reach(mdp.labels["success"]), _total(mdp, "mt"),
                       [_total(mdp, "rc")], on_solve)


def fastest(mdp: MDP, question: FastestQuestion, search: FrontSearch | None = None) -> Fastest:
    """The fastest strategy of *mdp* that meets *question* (its P(success) bound), from
    the front (*search*, made here if not given)."""
    p = float(question.bound)
    answer = (search or mission_front(mdp)).least_total_at(p)
    if answer is None:
        return _by_programme(mdp, question)
    return _from_front(question, answer)


def _from_front(question: FastestQuestion, answer: CertifiedAnswer) -> Fastest:
    p = float(question.bound)
    if not answer.achievable or answer.total is None:
        return Fastest(question.requirement, p, False, None, None, certified=True,
                       solves=answer.solves)
    time, recharges = answer.total, answer.extras[0]
    return Fastest(question.requirement, p, True, time.value, recharges.value, certified=True,
                   time_bounds=(time.lower, time.upper),
                   recharges_bounds=(recharges.lower, recharges.upper),
                   mixing=float(answer.mixing), solves=answer.solves)


def _by_programme(mdp: MDP, question: FastestQuestion) -> Fastest:
    """The linear programme's least time (not certified; no recharges)."""
    p = float(question.bound)
    answer = multi_optimum(mdp, _total(mdp, "mt"), "min",
                           [Constraint(Reach(mdp.labels["success"]), ">=", p)])
    if not answer.achievable or answer.value is None:
        return Fastest(question.requirement, p, False, None, None)
    return Fastest(question.requirement, p, True, answer.value, None)


def front(search: FrontSearch) -> tuple[FrontPoint, ...]:
    """Vertices of the Pareto front (certified points of deterministic strategies;
    every point between two neighbours is a mix of the two), enough that the line
    through them lies within :data:`FRONT_TOLERANCE` of the exact front."""
    return tuple(FrontPoint(v.p.value, v.total.value)
                 for v in search.front(FRONT_TOLERANCE).vertices)


def _total(mdp: MDP, name: str) -> Total:
    return Total(mdp.reward(name).per_choice(mdp))
