"""The witness strategies of ``multi(...)`` answers (checker/mdp/multi_strategy.py):
hand-solved models where only a randomised strategy (with memory) attains the answer,
and the refusals."""

from __future__ import annotations

import pytest

from veribattery.checker.mdp.multi_strategy import MultiStrategy, multi_strategy
from veribattery.checker.mdp.witness import NoStrategyError
from veribattery.lang import parse_model, parse_properties
from veribattery.lang.nodes import Multi
from veribattery.pipeline.mdp import MdpCheckRun, check_mdp_model

#: Two targets, each reachable by one choice: meeting P>=0.5 for both needs the
#: 50/50 mix of the two (every deterministic strategy reaches one with probability 1).
FORK = """mdp
module m
  s : [0..2] init 0;
  [left] s=0 -> (s'=1);
  [right] s=0 -> (s'=2);
  [] s>0 -> true;
endmodule
label "a" = s=1;
label "b" = s=2;
"""

#: A zero-reward end component {1, 3} entered at either state; it is left only from
#: s=3 by "go" (reward 1) into s=2 ("out"). Staying forever is a choice of its own.
REST = """mdp
module m
  s : [0..3] init 0;
  [start] s=0 -> 0.5:(s'=1) + 0.5:(s'=3);
  [wait] s=1 -> (s'=1);
  [over] s=1 -> (s'=3);
  [back] s=3 -> (s'=1);
  [go] s=3 -> (s'=2);
  [] s=2 -> true;
endmodule
rewards "r"
  [go] true : 1;
endrewards
label "out" = s=2;
"""


def _run(model: str, props: str) -> MdpCheckRun:
    return check_mdp_model(parse_model(model), parse_properties(props).properties)


def _strategy(run: MdpCheckRun, index: int = 0, value: object = None) -> MultiStrategy:
    result = run.results[index]
    formula = result.property.formula
    assert isinstance(formula, Multi)
    return multi_strategy(run.mdp, formula, result.value if value is None else value)


def _moves(run: MdpCheckRun, strategy: MultiStrategy, node: int) -> dict[tuple[str, bool], float]:
    """The node's moves: (action, switches the memory to stopped) -> probability."""
    return {(run.mdp.action_of(int(strategy.move_choice[m])), bool(strategy.move_stops[m])):
            float(strategy.move_probability[m]) for m in strategy.moves(node)}


def _node(run: MdpCheckRun, strategy: MultiStrategy, s: int, stopped: bool = False) -> int:
    """The node of the state with variable s = *s* (and the given mode)."""
    assert run.mdp.states is not None
    found = [k for k in range(strategy.num_nodes)
             if run.mdp.states[strategy.node_state[k], 0] == s
             and strategy.node_stopped[k] == stopped]
    assert len(found) == 1
    return found[0]


def test_two_bounds_at_one_half_need_the_even_mix() -> None:
    run = _run(FORK, 'multi(P>=0.5 [ F "a" ], P>=0.5 [ F "b" ])')
    assert run.results[0].value is True
    strategy = _strategy(run)
    assert strategy.num_nodes == 3 and not strategy.has_mode
    assert _moves(run, strategy, strategy.initial) == {
        ("left", False): pytest.approx(0.5, abs=1e-9),
        ("right", False): pytest.approx(0.5, abs=1e-9)}
    assert [v.value for v in strategy.values] == pytest.approx([0.5, 0.5], abs=1e-9)
    # The visited bits: "a" entered in s=1 only, "b" in s=2 only.
    assert strategy.node_visited[_node(run, strategy, 1)] == 0b01
    assert strategy.node_visited[_node(run, strategy, 2)] == 0b10


def test_a_numerical_optimum_mixes_as_the_bound_allows() -> None:
    """Pmax [F a] subject to P>=0.3 [F b]: left with 0.7, right with 0.3."""
    run = _run(FORK, 'multi(Pmax=? [ F "a" ], P>=0.3 [ F "b" ])')
    assert run.results[0].value == pytest.approx(0.7, abs=1e-9)
    strategy = _strategy(run)
    assert _moves(run, strategy, strategy.initial) == {
        ("left", False): pytest.approx(0.7, abs=1e-9),
        ("right", False): pytest.approx(0.3, abs=1e-9)}


def test_staying_in_a_zero_reward_component_with_some_probability_needs_the_mode() -> None:
    """Rmax [C] with P>=0.5 [G !out]: half the runs must stay in {1, 3} forever. Entered
    at s=1 or s=3 with 1/2 each; the optimum 0.5 leaves with probability exactly 1/2."""
    run = _run(REST, 'multi(R{"r"}max=? [ C ], P>=0.5 [ G !"out" ])')
    assert run.results[0].value == pytest.approx(0.5, abs=1e-9)
    strategy = _strategy(run)
    assert strategy.has_mode
    assert [v.value for v in strategy.values] == pytest.approx([0.5, 0.5], abs=1e-9)
    # Stopped: the inside choices only, forever.
    for s in (1, 3):
        node = _node(run, strategy, s, stopped=True)
        assert {a for a, _ in _moves(run, strategy, node)} <= {"wait", "over", "back"}
    # Running at s=3 the strategy goes, or stops; at s=1 it only ever stops (going
    # over to s=3 first would also work, but then stopping there, not going).
    running = _moves(run, strategy, _node(run, strategy, 3))
    assert running.get(("go", False), 0.0) + sum(
        p for (a, stops), p in running.items() if stops) == pytest.approx(1.0)


def test_an_achievability_query_with_a_stay_splits_the_runs() -> None:
    """R>=0.25 [C] with P>=0.75 [G !out]: the most-inside strategy leaves with 1/4."""
    run = _run(REST, 'multi(R{"r"}>=0.25 [ C ], P>=0.75 [ G !"out" ])')
    strategy = _strategy(run)
    reward, stay = (v.value for v in strategy.values)
    assert reward == pytest.approx(0.25, abs=1e-9) and stay == pytest.approx(0.75, abs=1e-9)


def test_a_strategy_that_misses_the_reported_optimum_is_refused() -> None:
    """The check bites: told the optimum were 0.6, the strategy (0.5) is not exported."""
    run = _run(REST, 'multi(R{"r"}max=? [ C ], P>=0.5 [ G !"out" ])')
    with pytest.raises(NoStrategyError, match=r"not = 0\.6 \(the optimum\) within 1e-06"):
        _strategy(run, value=0.6)


@pytest.mark.parametrize(("props", "message"), [
    ('multi(R{"r"}>=0.5 [ C<=2 ], P>=0.5 [ G !"out" ])', "C<=k objective"),
    ('multi(P>=0.6 [ F "out" ], P>=0.6 [ G !"out" ])', "no strategy meets every objective"),
    ('multi(Pmax=? [ F "out" ], P>=0.6 [ G !"out" ], P>=0.6 [ F "out" ])', "nan"),
    ('multi(R{"r"}max=? [ C ])', "inf"),
], ids=["cumulative", "false", "nan", "infinite"])
def test_refusals(props: str, message: str) -> None:
    run = _run(REST.replace("[go] true : 1;", "[go] true : 1;\n  [wait] true : 1;"), props)
    with pytest.raises(NoStrategyError, match=message):
        _strategy(run)


#: A zero-reward end component {1, 2, 3} entered at s=1; "pay" at s=2 (reward 1)
#: keeps the run inside it. The programme's uses of "pay" circulate between s=2 and
#: s=3 while the runs could stop at s=1 where they enter: the flows must be spread
#: over the component's inside choices before a run ever pays.
LOOP = """mdp
module m
  s : [0..3] init 0;
  [go] s=0 -> (s'=1);
  [wait] s=1 -> (s'=1);
  [move] s=1 -> (s'=2);
  [back] s=2 -> (s'=1);
  [pay] s=2 -> 0.5:(s'=2) + 0.5:(s'=3);
  [ret] s=3 -> (s'=2);
endmodule
rewards "r"
  [pay] true : 1;
endrewards
"""

#: Reward is earned only in a paying cycle at s=2, entered by a risk that reaches "a"
#: half the time; staying at s=0 is safe. Pmin [F a] subject to R>=1 [C] is 0 as an
#: infimum (risk with probability e, pay 2/e times), attained by no strategy with
#: finite reward (Storm: no Pareto-optimal scheduler with finite reward).
UNATTAINED = """mdp
module m
  s : [0..3] init 0;
  [safe] s=0 -> (s'=0);
  [risk] s=0 -> 0.5:(s'=1) + 0.5:(s'=2);
  [pay] s=2 -> (s'=2);
  [leave] s=2 -> (s'=3);
  [] s=1 | s=3 -> true;
endmodule
rewards "r"
  [pay] true : 1;
endrewards
label "a" = s=1;
"""


def test_a_paying_cycle_inside_a_resting_component_is_fed_from_its_entry() -> None:
    run = _run(LOOP, 'multi(R{"r"}>=2 [ C ], P>=1 [ F s=1 ])')
    strategy = _strategy(run)
    reward, _ = strategy.values
    assert reward.lower >= 2 - 1e-9
    entry = _moves(run, strategy, _node(run, strategy, 1))
    assert entry.get(("move", False), 0.0) > 0  # runs do go on from where they enter


def test_an_optimum_no_strategy_attains_is_refused() -> None:
    run = _run(UNATTAINED, 'multi(Pmin=? [ F "a" ], R{"r"}>=1 [ C ])')
    assert run.results[0].value == pytest.approx(0.0, abs=1e-6)
    with pytest.raises(NoStrategyError, match="never reaches"):
        _strategy(run)


def test_a_certified_enclosure_of_the_optimum_admits_the_programmes_optimum() -> None:
    """The two-objective front reports a certified interval whose point value may be
    off the optimum: a strategy attaining the programme's optimum (0.7) inside the
    interval passes; outside it, it is refused."""
    run = _run(FORK, 'multi(Pmax=? [ F "a" ], P>=0.3 [ F "b" ])')
    formula = run.results[0].property.formula
    assert isinstance(formula, Multi)
    passed = multi_strategy(run.mdp, formula, 0.71, (0.69, 0.72))
    assert passed.values[0].value == pytest.approx(0.7, abs=1e-9)
    with pytest.raises(NoStrategyError, match=r"certified in \[0\.705, 0\.72\]"):
        multi_strategy(run.mdp, formula, 0.71, (0.705, 0.72))
    with pytest.raises(NoStrategyError, match="the optimum"):
        multi_strategy(run.mdp, formula, 0.71)
