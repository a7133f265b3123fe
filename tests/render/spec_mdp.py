"""model-spec.md's mission MDP ("Synthesis"), written out in Python from the spec's
tables alone, for small farms: the reference the rendered PRISM model is compared with.

It shares nothing with the templates: only the config's derived numbers (costs in
units, the route's n/dist/step), which the DTMC's own tests already pin. Capacity,
voltage level, the choice table, effects and the wind are computed here, exactly.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from fractions import Fraction
from math import floor
from typing import NamedTuple

from veribattery.config import MissionConfig, derive_parameters


class State(NamedTuple):
    """The spec's six variables."""

    s: int
    k: int
    j: int
    b: int
    rc: int
    wsp: int


#: A choice: its action label and its successor distribution.
Choice = tuple[str, dict[State, Fraction]]


@dataclass(frozen=True)
class SpecMission:
    """The numbers of one config, as the spec names them."""

    c_new: int
    rc_max: int
    fade: Fraction
    v_high: Fraction
    v_low: Fraction
    fixed_level: int | None
    tl: tuple[tuple[int, ...], ...]  # [wind][level]
    cell: tuple[tuple[int, ...], ...]
    ins: tuple[tuple[int, ...], ...]
    n: tuple[int, ...]
    dist: tuple[int, ...]
    step: tuple[int, ...]
    p_wsp_c: Fraction

    @classmethod
    def of(cls, cfg: MissionConfig) -> SpecMission:
        p = derive_parameters(cfg)
        return cls(p.c_new, p.rc_max, Fraction(p.fade.num, p.fade.den),
                   Fraction(p.v_high.num, p.v_high.den), Fraction(p.v_low.num, p.v_low.den),
                   p.fixed_level, p.costs.takeoff_land, p.costs.cell, p.costs.inspection,
                   p.layout.n, p.layout.dist, p.layout.step, p.p_wsp_c)

    @property
    def K(self) -> int:
        return len(self.n)

    @property
    def initial(self) -> State:
        return State(0, 0, 0, self.c_new, 0, 0)

    def cap(self, rc: int) -> int:
        """cap(rc) = floor(C_NEW x (1 - fade x rc)), exactly."""
        return floor(self.c_new * (1 - self.fade * rc))

    def level(self, b: int, rc: int) -> int:
        """0 low, 1 medium, 2 high, from SOC = b / cap(rc)."""
        if self.fixed_level is not None:
            return self.fixed_level
        soc = Fraction(b, self.cap(rc))
        return 2 if soc > self.v_high else 0 if soc < self.v_low else 1

    def costs(self, x: State) -> tuple[int, int, int]:
        """c_tl, c_cell, c_ins at x's wind and voltage level."""
        lvl = self.level(x.b, x.rc)
        return self.tl[x.wsp][lvl], self.cell[x.wsp][lvl], self.ins[x.wsp][lvl]

    def choices(self, x: State) -> list[Choice]:
        """The spec's choice table at *x*; absorbing states loop unlabelled."""
        if x.s >= 6:
            return [("", {x: Fraction(1)})]
        return [(action, self._wind(after)) for action, after in self._moves(x)]

    def _wind(self, after: State) -> dict[State, Fraction]:
        """One step in which the wind flips with probability p_wsp_c."""
        out: dict[State, Fraction] = {}
        for wsp, prob in ((1 - after.wsp, self.p_wsp_c), (after.wsp, 1 - self.p_wsp_c)):
            if prob:
                key = after._replace(wsp=wsp)
                out[key] = out.get(key, Fraction(0)) + prob
        return out

    def _moves(self, x: State) -> Iterator[tuple[str, State]]:
        """(action, state after it, wind not yet moved) for each choice at a live *x*."""
        tl, cell, ins = self.costs(x)
        s, k, j, b, rc, _ = x
        fail = x._replace(s=6, b=0)
        if s == 5:
            if k == self.K:
                yield "finish", x._replace(s=7)
            elif rc < self.rc_max:
                yield "recharge", x._replace(s=0, rc=rc + 1, b=self.cap(rc + 1))
            else:
                yield "oob", fail
            return
        if s == 0 and x.wsp == 1:
            yield "wait", x
            return
        fly = self.dist[k] * cell if k < self.K else None
        if s == 0 and tl <= b:
            yield "takeoff", x._replace(s=1, b=b - tl)
        if s == 1 and fly is not None and fly <= b:
            yield "fly", x._replace(s=2, b=b - fly)
        if s in (1, 4) and tl <= b:
            yield "land", x._replace(s=5, b=b - tl)
        if s == 2 or (s == 3 and j < self.n[k]):
            if ins <= b:
                yield "inspect", x._replace(s=3, j=j + 1, b=b - ins)
            if fly is not None and fly <= b:
                yield "back", x._replace(s=4, b=b - fly)
        if s == 3 and j == self.n[k]:
            if k < self.K - 1 and self.step[k] * cell <= b:
                yield "next", x._replace(s=2, k=k + 1, j=0, b=b - self.step[k] * cell)
            if fly is not None and fly <= b:
                yield "backnext", x._replace(s=4, k=k + 1, j=0, b=b - fly)
        yield "abort", fail

    def reachable(self) -> dict[State, list[Choice]]:
        """Every reachable state and its choices, breadth first from the initial state."""
        seen = {self.initial: self.choices(self.initial)}
        queue = deque([self.initial])
        while queue:
            for _, dist in seen[queue.popleft()]:
                for y in dist:
                    if y not in seen:
                        seen[y] = self.choices(y)
                        queue.append(y)
        return seen


def max_success(model: dict[State, list[Choice]]) -> dict[State, Fraction]:
    """Pmax of reaching s=7, exactly, state by state in reverse topological order.

    The spec says the MDP is acyclic apart from self-loops: a choice that stays with
    probability q < 1 is worth its other successors' value over 1 - q (a sure self-loop,
    absorbing, keeps its own value). A longer cycle raises.
    """
    value: dict[State, Fraction] = {}
    for x in _post_order(model):
        options = [sum((p * value[y] for y, p in dist.items() if y != x), Fraction(0))
                   / (1 - dist.get(x, Fraction(0)))
                   for _, dist in model[x] if dist.get(x) != 1]
        value[x] = max(options) if options else Fraction(int(x.s == 7))
    return value


def _post_order(model: dict[State, list[Choice]]) -> list[State]:
    """Every state after all its successors other than itself; raises on a longer cycle."""
    done: set[State] = set()
    order: list[State] = []
    for root in model:
        if root in done:
            continue
        path, stack = {root}, [(root, iter(_successors(model, root)))]
        while stack:
            x, successors = stack[-1]
            y = next(successors, None)
            if y is None:
                stack.pop()
                path.discard(x)
                done.add(x)
                order.append(x)
            elif y in path:
                raise AssertionError(f"a cycle through {x} and {y}")
            elif y not in done:
                path.add(y)
                stack.append((y, iter(_successors(model, y))))
    return order


def _successors(model: dict[State, list[Choice]], x: State) -> set[State]:
    return {y for _, dist in model[x] for y in dist if y != x}
