"""Reward-bound layers solved in one pass where their cost-free choices have no cycle
(:mod:`veribattery.checker.mdp.reward_levels`): QVBS's exact values on firewire, Storm's
exact values on random timed MDPs, rational values of random layers, the general
solve's bounds where the pass applies, and the general solve where it does not."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker.mdp.test_reward_bounded_mdp import REPO
from tests.checker.test_reward_epochs import FAR_GOAL
from tests.strategies.models import ROBOT
from veribattery.checker.kernels import reward_layers
from veribattery.checker.mdp.reward_levels import LevelledLayers
from veribattery.pipeline import check_prism_file

FIREWIRE = REPO / "bench/qcomp/firewire"

#: A cost-free loop: from x=0 the free choice [a] returns to x=0 half the time.
LOOP = """mdp
module m
  x : [0..2] init 0;
  [a] x=0 -> 0.5:(x'=0) + 0.5:(x'=1);
  [b] x=0 -> (x'=1);
  [c] x=1 -> 0.5:(x'=2) + 0.5:(x'=0);
endmodule
rewards "r"
  [b] true : 1;
  [c] true : 1;
endrewards
label "goal" = x=2;
"""


class _Counted:
    """LevelledLayers' calls and how many it answered (the others: the general solve)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, *, off: bool = False) -> None:
        self.calls = self.answered = 0
        original = LevelledLayers.__call__

        def counted(layers: LevelledLayers, *args: np.ndarray) -> object:
            self.calls += 1
            found = None if off else original(layers, *args)
            self.answered += found is not None
            return found

        monkeypatch.setattr(LevelledLayers, "__call__", counted)


@pytest.fixture
def layers(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(reward_layers, "PRODUCT_LIMIT", 0)


def _bounds(prop: str, model: str | Path, **constants: str) -> tuple[float, float, float]:
    """The bounds of *prop*: a property, or the name of one of firewire's."""
    named = not prop.startswith("P")
    run = check_prism_file(model, props_source=FIREWIRE / "firewire.false.props" if named
                           else prop, constants=constants or None,
                           selectors=(prop,) if named else None)
    found = run.results[0]
    assert found.certified and found.precise
    return float(found.value), float(found.lower), float(found.upper)


@pytest.mark.usefixtures("layers")
@pytest.mark.parametrize(("deadline", "expected"),
                         [(200, Fraction(1, 2)), (400, Fraction(25, 32))])
def test_firewire_deadline_in_one_pass_per_layer(monkeypatch: pytest.MonkeyPatch,
                                                 deadline: int, expected: Fraction) -> None:
    """QVBS's exact results (Storm's exact engine) for firewire.false, delay 3: every
    cycle costs time, so every layer after the first is one pass."""
    counted = _Counted(monkeypatch)
    value, lower, upper = _bounds("deadline", FIREWIRE / "firewire.false.prism",
                                  delay="3", deadline=str(deadline))
    assert Fraction(lower) <= expected <= Fraction(upper)
    assert value == pytest.approx(float(expected), abs=1e-12)
    assert counted.answered == counted.calls > deadline // 2


@pytest.mark.usefixtures("layers")
@pytest.mark.parametrize("prop", [f'P{d}=? [ F{{"{r}"}}<={k} "goal" ]'
                                  for d in ("min", "max") for k in (1, 3, 6)
                                  for r in ("steps", "time")]
                         + ['Pmax=? [ !"broken" U{"steps"}<=4 "goal" ]']
                         + [f'P{d}=? [ F{{"time"}}>={k} "goal" ]' for d in ("min", "max")
                            for k in (2, 5)])
def test_the_pass_meets_the_general_solve(monkeypatch: pytest.MonkeyPatch, prop: str) -> None:
    counted = _Counted(monkeypatch)
    passed = _bounds(prop, ROBOT)
    # (gathering ">=", the goal's loop costs no time and is passed through on the layers
    # above 0: a cost-free cycle, the general solve's)
    assert counted.answered > 0 if "<=" in prop else counted.answered == 0
    monkeypatch.undo()
    monkeypatch.setattr(reward_layers, "PRODUCT_LIMIT", 0)
    _Counted(monkeypatch, off=True)
    general = _bounds(prop, ROBOT)
    assert passed[1] <= general[2] and general[1] <= passed[2]
    assert passed[0] == pytest.approx(general[0], abs=1e-12)


@pytest.mark.usefixtures("layers")
def test_exact_zeros_stay_exact_in_the_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    counted = _Counted(monkeypatch)
    assert _bounds('Pmax=? [ F{"r"}<=4 "goal" ]', FAR_GOAL) == (0.0, 0.0, 0.0)
    assert counted.answered == counted.calls == 5


@pytest.mark.usefixtures("layers")
@pytest.mark.parametrize(("budget", "expected"), [
    # From x=0 the free loop [a] reaches x=1 almost surely; there each try of [c] pays 1
    # and reaches the goal half the time. Budget T: Pmax = 1 - (1/2)^T.
    (1, Fraction(1, 2)), (2, Fraction(3, 4)), (4, Fraction(15, 16)),
    (7, Fraction(127, 128))])
def test_a_cost_free_loop_takes_the_general_solve(monkeypatch: pytest.MonkeyPatch,
                                                  budget: int, expected: Fraction) -> None:
    counted = _Counted(monkeypatch)
    value, lower, upper = _bounds(f'Pmax=? [ F{{"r"}}<={budget} "goal" ]', LOOP)
    assert Fraction(lower) <= expected <= Fraction(upper)
    assert value == pytest.approx(float(expected), abs=1e-12)
    assert counted.calls > 0 and counted.answered == 0


def _five_states() -> tuple[sp.csr_matrix, np.ndarray]:
    """States 0-2 keep their place (self-loops); state 3 has three cost-free choices,
    state 4 a cost-free one to 3 and one that leaves the layer (row 7)."""
    rows = [[(0, 1.0)], [(1, 1.0)], [(2, 1.0)],
            [(0, 0.5), (1, 0.5)], [(2, 1.0)], [(1, 1.0)],
            [(3, 1.0)], [(0, 1.0)]]
    matrix = sp.csr_matrix(([p for r in rows for _, p in r],
                            ([i for i, r in enumerate(rows) for _ in r],
                             [t for r in rows for t, _ in r])), shape=(8, 5))
    return matrix, np.array([0, 1, 2, 3, 6, 8])


@pytest.mark.parametrize(("objective", "expected"), [("max", [1.0, 1.0]),
                                                     ("min", [0.0, 0.0])])
def test_one_layer_by_hand(objective: str, expected: list[float]) -> None:
    matrix, groups = _five_states()
    costs = np.array([0, 0, 0, 0, 0, 0, 0, 1])
    remain = np.array([False, False, False, True, True])  # (0 and 1 do not move: 0)
    target = np.array([False, False, True, False, False])
    solve = LevelledLayers(matrix, groups, costs, objective,  # type: ignore[arg-type]
                           remain, target)
    exits = np.zeros(8)
    exits[7] = 0.25
    found = solve(remain, target, exits, exits)
    assert found is not None
    assert np.all(found.lower <= [0.0, 0.0, 1.0, *expected])
    assert np.all(found.upper >= [0.0, 0.0, 1.0, *expected])
    assert np.all(found.upper - found.lower <= 4e-15)  # (a few ulps a level)
    # State 3 loses its way to the target: its best is 0, and state 4's the exit's 1/4.
    found = solve(remain, np.zeros(5, dtype=bool), exits, exits)
    assert found is not None
    best = 0.25 if objective == "max" else 0.0
    assert found.lower[:4].tolist() == found.upper[:4].tolist() == [0.0] * 4  # (exact 0s)
    assert found.lower[4] <= best <= found.upper[4] <= best + 1e-15


def test_a_cost_free_cycle_is_not_passed() -> None:
    matrix, groups = _five_states()
    looped = matrix.toarray()
    looped[6] = [0, 0, 0, 0.5, 0.5]  # state 4 may stay where it is
    remain = np.array([False, False, False, True, True])
    target = np.array([False, False, True, False, False])
    solve = LevelledLayers(sp.csr_matrix(looped), groups, np.zeros(8, dtype=np.int64), "max",
                           remain, target)
    exits = np.zeros(8)
    assert solve(remain, target, exits, exits) is None


@pytest.mark.parametrize(("seed", "objective"), [(s, o) for s in range(4) for o in ("min", "max")])
def test_random_layers_enclose_their_exact_values(seed: int, objective: str) -> None:
    """Random layers whose cost-free choices lead to lower states (no cycle), solved in
    rationals level by level (each row's mass over its sum, as the pass divides)."""
    rng = np.random.default_rng(seed)
    n, rows, groups, costs = 60, [], [0], []
    for state in range(n):
        for _ in range(1 if state < 3 else int(rng.integers(1, 4))):
            if state < 3:  # (0 and 1 fail, 2 is the target: self-loops)
                rows.append({state: 1.0})
            else:
                picked = rng.choice(state, size=min(state, int(rng.integers(1, 4))),
                                    replace=False)
                weights = rng.random(picked.size) + 0.05
                rows.append(dict(zip(picked.tolist(), (weights / weights.sum()).tolist(),
                                     strict=True)))
            costs.append(int(state >= 3 and rng.random() < 0.3))
        groups.append(len(rows))
    matrix = sp.csr_matrix(([p for r in rows for p in r.values()],
                            ([i for i, r in enumerate(rows) for _ in r],
                             [t for r in rows for t in r])), shape=(len(rows), n))
    remain = np.arange(n) >= 3
    target = np.arange(n) == 2
    # An exit leads to the successors' values on a lower layer: 0 unless one of them has
    # a path to the target (so the pass's states without one are 0 on every layer).
    hopeful = [False, False, True]
    for state in range(3, n):
        hopeful.append(any(hopeful[t] for r in range(groups[state], groups[state + 1])
                           for t in rows[r]))
    leads = np.array([any(hopeful[t] for t in row) for row in rows])
    exits = rng.random(len(rows)) * (np.array(costs) > 0) * leads
    solve = LevelledLayers(matrix, np.array(groups), np.array(costs), objective,  # type: ignore[arg-type]
                           remain, target)
    found = solve(remain, target, exits, exits)
    assert found is not None
    exact = [Fraction(0), Fraction(0), Fraction(1)]
    pick = max if objective == "max" else min
    for state in range(3, n):
        images = []
        for row in range(groups[state], groups[state + 1]):
            if costs[row]:
                images.append(Fraction(float(exits[row])))
            else:
                mass = [(Fraction(p), t) for t, p in rows[row].items()]
                images.append(sum(p * exact[t] for p, t in mass) / sum(p for p, _ in mass))
        exact.append(pick(images))
    for low, high, value in zip(found.lower, found.upper, exact, strict=True):
        assert Fraction(float(low)) <= value <= Fraction(float(high))
        assert float(high - low) <= 1e-13


def test_values_near_underflow_take_the_general_solve() -> None:
    """The a priori bound needs every product of a value and a probability (here 1/2)
    above 2**-1000 (~1e-301): an exit of 1e-290 is passed, one of 1e-302 is not."""
    matrix, groups = _five_states()
    costs = np.array([0, 0, 0, 0, 0, 0, 0, 1])
    remain = np.array([False, False, False, True, True])
    target = np.array([False, False, True, False, False])
    solve = LevelledLayers(matrix, groups, costs, "max", remain, target)
    for exit_value, passed in ((1e-290, True), (1e-302, False)):
        exits = np.zeros(8)
        exits[7] = exit_value
        # (without the target, state 3 is 0 and state 4 takes the exit)
        found = solve(remain, np.zeros(5, dtype=bool), exits, exits)
        assert (found is not None) is passed


def _random_timed_mdp(seed: int) -> str:
    """A random MDP of two modules whose every cycle costs time (each step of a module
    that advances its clock costs 1; the others move forward in a counter), with a goal,
    a failure sink and cost-free choices among them."""
    rng = np.random.default_rng(seed)
    lines = ["mdp", "module m", "  x : [0..6] init 0;", "  c : [0..3] init 0;"]
    for x in range(5):
        for action in ("a", "b"):
            p = round(float(rng.uniform(0.1, 0.9)), 3)
            up = min(6, x + int(rng.integers(1, 3)))
            back = int(rng.integers(0, x + 1))
            lines.append(f"  [{action}] x={x} & c<3 -> {p}:(x'={up})&(c'=c+1) + "
                         f"{round(1 - p, 3)}:(x'={back})&(c'=c+1);")
        q = round(float(rng.uniform(0.2, 0.8)), 3)
        lines.append(f"  [free] x={x} & c=3 -> {q}:(x'=min(6,x+1))&(c'=0) + "
                     f"{round(1 - q, 3)}:(x'=6)&(c'=0);")
    lines += ["  [fail] x=6 -> true;", "  [done] x=5 -> true;", "endmodule",
              'rewards "time"', "  [a] true : 1;", "  [b] true : 2;", "endrewards",
              'label "goal" = x=5;']
    return "\n".join(lines) + "\n"


@pytest.mark.usefixtures("layers")
@pytest.mark.parametrize("seed", range(4))
def test_layers_in_one_pass_against_storm(monkeypatch: pytest.MonkeyPatch, seed: int,
                                          tmp_path: Path) -> None:
    """Storm's exact values (its epochs) on random timed MDPs, forced through the
    layers here: every layer but the first in one pass."""
    pytest.importorskip("stormpy")
    from tests.storm_oracle import storm_initial_values

    text = _random_timed_mdp(seed)
    props = [f'P{d}=? [ F{{"time"}}<={k} "goal" ]' for d in ("min", "max") for k in (3, 8, 25)]
    storm = storm_initial_values(text, props, tmp_path)
    counted = _Counted(monkeypatch)
    for prop, theirs in zip(props, storm, strict=True):
        value, lower, upper = _bounds(prop, text)
        assert lower <= theirs <= upper  # (the nearest double of an enclosed rational)
        assert value == pytest.approx(theirs, rel=1e-9, abs=1e-12)
    assert counted.answered > 0


def test_layers_in_one_pass_are_taken_below_the_product_limit(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """firewire at delay=3 (4,093 states): 201 layers in one pass each, not the product
    of 201 copies (0.9 s and 77 MB against 3.2 s and 763 MB at deadline=800); a lower
    bound, whose layers pass through the target, still builds the product."""
    counted = _Counted(monkeypatch)
    _, lower, upper = _bounds("deadline", FIREWIRE / "firewire.false.prism",
                              delay="3", deadline="200")
    assert lower <= 0.5 <= upper and counted.answered == counted.calls == 201
    _bounds('Pmax=? [ F{"r"}>=2 "goal" ]', FAR_GOAL)
    assert counted.calls == 201
