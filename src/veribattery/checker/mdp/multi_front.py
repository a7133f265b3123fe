"""The Pareto front of one reachability probability against one expected total reward,
and ``multi(R min=? [ C ], P>=p [ F T ])`` answered from it, certified, without a
linear programme.

The front of the achievable points (P(F T), E[R]) is convex, and its vertices are
the points of deterministic strategies that optimise a weighted sum
``E[R] + lam (1 - P)`` (:mod:`~veribattery.checker.mdp.multi_weighted`). Its vertices
are found by dichotomic search (Aneja & Nair 1979; Forejt, Kwiatkowska & Parker, ATVA
2012): ``lam = 0`` gives the fastest strategy's point *A*; ``lam = inf`` (the most
probable, then the least reward) gives *B*, with ``P = Pmax``. Between two known
vertices, the weight orthogonal to their segment either finds a point strictly below
it (a new vertex: both halves are searched) or shows that the segment is an edge.

The least E[R] among the strategies with ``P >= p`` is then a certified interval:

- *upper*: the two vertices *L* and *H* that bracket *p*, mixed once at the start with
  the weight *w* that makes ``w P_H + (1 - w) P_L >= p`` on their certified lower
  bounds: that randomised strategy meets *p*, and its E[R] is at most
  ``w R_H + (1 - w) R_L`` on their certified upper bounds;
- *lower*: for every weight solved, ``V(lam) <= E[R] + lam (1 - P) <= E[R] + lam (1 - p)``
  for every strategy with ``P >= p``, so ``V_lower(lam) - lam (1 - p)`` bounds the
  optimum from below (on the edge that holds *p*, this is the interpolation again).

Both are computed in rationals from the certified floats and rounded outwards.
Ties between optimal strategies are broken by the engine's policy iteration
(deterministic); a tie can only add a point on an edge of the front, never move it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from fractions import Fraction

from veribattery._types import IntArray
from veribattery.checker.mdp.model import MDP
from veribattery.checker.mdp.multi import Reach, Total
from veribattery.checker.mdp.multi_weighted import (
    Interval,
    Point,
    StoppingMdp,
    WeightedOptimum,
    down,
    up,
)
from veribattery.checker.mdp.optimum import Equations, Problem
from veribattery.checker.mdp.strategy import Strategy

__all__ = ["CertifiedAnswer", "Front", "FrontSearch", "least_total_at", "pareto_front"]

#: A weight's optimum counts as a new vertex only if it lies below the segment by more
#: than this, relative: closer, the segment is taken as an edge (the lower bound still
#: comes from the certified optimum, so the answer's interval stays true).
BELOW = 1e-10
#: Bisection rounds of one numerical query before the bracket is taken as it is.
MAX_SPLITS = 200
#: Strategies kept to start policy iteration from (the most recent weights'; each is
#: an array over the system's classes, tens of MB on the paper's baseline).
STARTS_KEPT = 4


@dataclass(frozen=True, slots=True)
class Front:
    """The vertices of the Pareto front, by increasing P (empty: no strategy has a
    finite total reward).

    :param pmax: ``Pmax`` of the target (certified), the top of the front.
    :param complete: whether the front reaches ``Pmax`` (False when the most
        probable strategies need an infinite total reward: the last vertex is then
        the safest one found by the weights).
    :param solves: the weighted optima solved.
    """

    vertices: tuple[Point, ...]
    pmax: Interval
    complete: bool
    solves: int


@dataclass(frozen=True, slots=True)
class CertifiedAnswer:
    """The least expected total reward among the strategies with ``P >= p``.

    :param achievable: whether some strategy (with finite total reward) meets *p*
        (certified).
    :param total: the optimum: certified ``[lower, upper]``, *value* the mixed
        strategy's point value (None when not achievable).
    :param strategies: the deterministic strategies mixed: *low* (P below *p*, or the
        only one) and *high*.
    :param mixing: the probability of following the last of *strategies*.
    :param extras: the mixed strategy's extra totals, certified.
    :param solves: the weighted optima solved so far.
    """

    achievable: bool
    total: Interval | None
    strategies: tuple[Point, ...] = ()
    mixing: Fraction = Fraction(0)
    extras: tuple[Interval, ...] = ()
    solves: int = 0


class FrontSearch:
    """Weighted optima of one MDP, solved as needed and kept (the caller owns it)."""

    def __init__(self, mdp: MDP, reach: Reach, total: Total,
                 extras: Sequence[Total] = (),
                 on_solve: Callable[[int], None] | None = None) -> None:
        """:param on_solve: told the number of weighted optima solved after each (a
            search may take minutes at the paper's scale)."""
        self.stopping = StoppingMdp.of(mdp, reach, total, extras)
        self._on_solve = on_solve
        self._optima: dict[float, WeightedOptimum] = {}
        self._starts: dict[float, IntArray] = {}  # positive weight -> rows, the latest
        self._problems: dict[bool, tuple[Problem, Equations | None]] = {}
        self._safest: tuple[Interval, Point] | None = None

    @property
    def solves(self) -> int:
        """The weighted optima solved so far."""
        return len(self._optima)

    def optimum(self, lam: float) -> WeightedOptimum:
        """``min E[R] + lam (1 - P)`` (pre-passes and equations shared between weights;
        policy iteration started from the strategy of the closest positive weight solved).
        """
        if lam not in self._optima:
            positive = lam > 0
            if positive not in self._problems:
                problem = self.stopping.problem(lam)
                equations = (Equations.of(self.stopping.mdp, problem)
                             if problem.unknown.any() else None)
                self._problems[positive] = (problem, equations)
            problem, equations = self._problems[positive]
            found = self.stopping.optimum(lam, problem, self._closest(lam), equations)
            if positive and found.rows is not None:
                self._starts[lam] = found.rows
                while len(self._starts) > STARTS_KEPT:
                    del self._starts[next(iter(self._starts))]
            self._optima[lam] = replace(found, rows=None)
            if self._on_solve is not None:
                self._on_solve(self.solves)
        return self._optima[lam]

    def _closest(self, lam: float) -> IntArray | Strategy | None:
        """The rows of the kept positive weight closest to *lam* (by ratio); before
        any, the strategy of *B* if known (on the paper's baseline the first weight
        then takes 8 s instead of 120)."""
        if lam <= 0:
            return None
        if not self._starts:
            return None if self._safest is None else self._safest[1].strategy
        return self._starts[min(self._starts, key=lambda w: abs(math.log(w / lam)))]

    def fastest(self) -> Point | None:
        """*A*: the point of least E[R] (None: no strategy has a finite one)."""
        found = self.optimum(0.0)
        return found.point if math.isfinite(found.value.value) else None

    def safest(self) -> tuple[Interval, Point]:
        """``Pmax`` and *B*, the fastest of the most probable strategies."""
        if self._safest is None:
            self._safest = self.stopping.safest()
        return self._safest

    def front(self, tolerance: float = 0.0) -> Front:
        """The vertices from *A* to *B*: all of them, or (*tolerance* > 0) enough that
        the line through them lies above the front by at most *tolerance* times
        ``max(1, E[R])`` (a segment is not searched further once the certified optimum
        of its weight shows that; every point kept is still a strategy's own)."""
        low = self.fastest()
        pmax, high = self.safest()
        if low is None:
            return Front((), pmax, False, self.solves)
        complete = math.isfinite(high.total.value)
        if not complete:
            high = self.optimum(_steep(low)).point
        found = [low, high]
        segments = [(low, high)]
        while segments:
            left, right = segments.pop()
            middle = self._split(left, right)
            if middle is not None:
                found.append(middle)
                if self._gap(left, right) > tolerance:
                    segments += [(left, middle), (middle, right)]
        return Front(tuple(_undominated(found)), pmax, complete, self.solves)

    def least_total_at(self, p: float) -> CertifiedAnswer | None:
        """The least E[R] with ``P >= p`` (None: *p* lies within the certified interval
        of ``Pmax`` but above what the safest strategy found certainly meets, or the
        most probable strategies need an infinite total: undecided here)."""
        low = self.fastest()
        if low is None:
            return CertifiedAnswer(False, None, solves=self.solves)
        if low.p.lower >= p:
            return self._answer(low, low, p)
        pmax, high = self.safest()
        if p > pmax.upper:
            return CertifiedAnswer(False, None, solves=self.solves)
        if not math.isfinite(high.total.value) or high.p.lower < p:
            return None
        for _ in range(MAX_SPLITS):
            middle = self._split(low, high)
            if middle is None:
                break
            if middle.p.lower >= p:
                high = middle
            else:
                low = middle
        return self._answer(low, high, p)

    def _split(self, left: Point, right: Point) -> Point | None:
        """The optimum of the weight orthogonal to the segment, if strictly below it."""
        rise = right.total.value - left.total.value
        run = right.p.value - left.p.value
        if run <= 0 or rise < 0:
            return None
        lam = rise / run
        point = self.optimum(lam).point
        line = left.total.value + lam * (1.0 - left.p.value)
        weighted = point.total.value + lam * (1.0 - point.p.value)
        inside = left.p.value < point.p.value < right.p.value
        return point if inside and weighted < line - BELOW * max(1.0, abs(line)) else None

    def _gap(self, left: Point, right: Point) -> float:
        """How far above the front the segment may lie, relative to ``max(1, E[R])`` of
        its faster end: its weighted value less the certified lower bound of its weight's
        optimum bounds the distance all along it."""
        lam = (right.total.value - left.total.value) / (right.p.value - left.p.value)
        line = left.total.value + lam * (1.0 - left.p.value)
        return (line - self.optimum(lam).value.lower) / max(1.0, abs(left.total.value))

    def _answer(self, low: Point, high: Point, p: float) -> CertifiedAnswer:
        """*low* and *high* mixed to meet *p*, and the interval of the optimum."""
        mixing = _mixing(low.p.lower, high.p.lower, p)
        total = _mixed(low.total, high.total, mixing)
        lower = max(_supporting(o, p) for o in self._optima.values())
        upper = total.upper
        value = min(max(total.value, lower), upper)
        extras = tuple(_mixed(a, b, mixing) for a, b in zip(low.extras, high.extras,
                                                            strict=True))
        pair = (low,) if low is high else (low, high)
        return CertifiedAnswer(True, Interval(value, lower, upper), pair, mixing, extras,
                               self.solves)


def pareto_front(mdp: MDP, reach: Reach, total: Total, extras: Sequence[Total] = ()) -> Front:
    """The vertices of the front of (P(F target), E[total]) (:class:`FrontSearch`)."""
    return FrontSearch(mdp, reach, total, extras).front()


def least_total_at(mdp: MDP, reach: Reach, total: Total, p: float,
                   extras: Sequence[Total] = ()) -> CertifiedAnswer | None:
    """``multi(R min=? [ C ], P>=p [ F target ])``, certified (None: undecided here,
    :meth:`FrontSearch.least_total_at`)."""
    return FrontSearch(mdp, reach, total, extras).least_total_at(p)


def _mixing(low: float, high: float, p: float) -> Fraction:
    """The least weight on *high* whose mix with *low* has P >= *p* (P's lower bounds)."""
    if low >= p or high <= low:
        return Fraction(0) if low >= p else Fraction(1)
    return min(Fraction(1), (Fraction(p) - Fraction(low)) / (Fraction(high) - Fraction(low)))


def _mixed(low: Interval, high: Interval, weight: Fraction) -> Interval:
    """The enclosure of ``weight * high + (1 - weight) * low``."""
    if weight == 0 or weight == 1:
        return high if weight == 1 else low
    value = float(weight) * high.value + float(1 - weight) * low.value

    lower = _blend(low.lower, high.lower, weight, below=True)
    upper = _blend(low.upper, high.upper, weight, below=False)
    return Interval(min(max(value, lower), upper), lower, upper)


def _blend(a: float, b: float, weight: Fraction, *, below: bool) -> float:
    """``weight * b + (1 - weight) * a`` rounded down (*below*) or up."""
    if not (math.isfinite(a) and math.isfinite(b)):
        return a + b  # an infinite bound stays infinite
    exact = weight * Fraction(b) + (1 - weight) * Fraction(a)
    return down(exact) if below else up(exact)


def _supporting(optimum: WeightedOptimum, p: float) -> float:
    """``V_lower(lam) - lam (1 - p)``, rounded down: no strategy with P >= p does better."""
    if not math.isfinite(optimum.value.lower):
        return -math.inf
    lam = Fraction(optimum.lam)
    return down(Fraction(optimum.value.lower) - lam * (1 - Fraction(p)))


def _steep(low: Point) -> float:
    """A weight under which missing the target costs more than any reward of *low*."""
    return 1e6 * max(1.0, low.total.value)


def _undominated(points: list[Point]) -> list[Point]:
    """The *points* no other one beats (P at least as high, E[R] lower or P higher and
    E[R] as low), by increasing P: the weight 0 may pick, among the strategies of
    least E[R], one that is not the safest, and repeats go."""
    kept: list[Point] = []
    for point in sorted(points, key=lambda v: (-v.p.value, v.total.value)):
        if not kept or point.total.value < kept[-1].total.value:
            kept.append(point)
    return kept[::-1]
