"""Monte-Carlo simulation against exact values, with fixed seeds (so every run is deterministic)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.checker.chains import dtmc
from veribattery.analyses import simulate as simulation
from veribattery.analyses.observers import Observer
from veribattery.analyses.simulate import _Sampler, _Tally, path_table, simulate
from veribattery.checker import check
from veribattery.errors import CheckError
from veribattery.explore import build_dtmc
from veribattery.explore.dtmc import DTMC
from veribattery.lang import Property, flatten_model, parse_model, parse_property

# The loop of test_explain, with a reward of 1 per step outside {2, 3} and 2 on leaving 1.
LOOP = {0: {1: 0.5, 2: 0.3, 3: 0.2}, 1: {0: 0.4, 3: 0.1, 2: 0.5}}
PROPERTIES = (
    'P=? [ F "bad" ]',  # 5/16
    'P=? [ F<=3 "bad" ]',
    'P=? [ X "good" ]',  # 3/10
    'P=? [ G !"bad" ]',  # 11/16
    'P=? [ s<2 U "good" ]',
    'R{"r"}=? [ F "done" ]',
    'R{"r"}=? [ C<=2 ]',
    'R{"r"}=? [ I=1 ]',
)


def _loop() -> DTMC:
    return dtmc(LOOP, 4, labels={"bad": [3], "good": [2], "done": [2, 3]},
                rewards={"r": ([1, 1, 0, 0], [0, 2, 0, 0])})


def _props() -> list[Property]:
    return [parse_property(text) for text in PROPERTIES]


def test_estimates_agree_with_exact_values() -> None:
    chain = _loop()
    exact = {p.text: check(chain, p).value for p in _props()}
    assert exact['P=? [ F "bad" ]'] == pytest.approx(5 / 16)
    sim = simulate(chain, _props(), runs=20_000, seed=7, exact=exact)
    assert [e.text for e in sim.estimates] == list(PROPERTIES)
    for e in sim.estimates:
        assert e.runs == 20_000 and e.undecided == 0
        assert e.ci95[0] <= e.estimate <= e.ci95[1]
        assert e.ci999[0] <= e.exact <= e.ci999[1], e
        assert not e.disagrees
    assert sim.warnings() == ()


def test_runs_in_batches_agree_with_exact_values(monkeypatch: pytest.MonkeyPatch) -> None:
    """20 batches of 1,000 runs: every run counted, every estimate where one batch of
    20,000 puts it (within its 99.9 % interval), infinite rewards still infinite, and the
    paths recorded from the first batch."""
    chain = _loop()
    props = [*_props(), parse_property('R{"r"}=? [ F "bad" ]')]
    exact = {p.text: check(chain, p).value for p in props}
    monkeypatch.setattr(simulation, "BATCH_RUNS", 1_000)
    sim = simulate(chain, props, runs=20_000, seed=7, exact=exact, record=3)
    for e in sim.estimates:
        assert e.runs == 20_000 and e.undecided == 0
        assert not e.disagrees, e
    assert sim.estimates[-1].estimate == math.inf
    assert len(sim.paths) == 3 and all(path[0] == 0 for path in sim.paths)


def test_pooled_batches_are_the_whole_sample_s_statistics() -> None:
    """The pooled mean and standard deviation of uneven batches, against numpy's over all
    values; one batch is numpy's own arithmetic, bit for bit."""
    rng = np.random.default_rng(5)
    values = rng.exponential(3.0, 10_000)
    decided = rng.random(values.size) < 0.9
    tally, whole = _Tally(), _Tally()
    for lo, hi in ((0, 17), (17, 4_000), (4_000, 4_001), (4_001, 10_000)):
        tally.add(_observer(values[lo:hi], decided[lo:hi]))
    whole.add(_observer(values, decided))
    kept = values[decided]
    assert tally.n == whole.n == kept.size and tally.undecided == int((~decided).sum())
    assert tally.mean == pytest.approx(np.mean(kept), rel=1e-14)
    assert tally.std == pytest.approx(np.std(kept, ddof=1), rel=1e-12)
    assert (whole.mean, whole.std) == (float(np.mean(kept)), float(np.std(kept, ddof=1)))


def _observer(values: np.ndarray, decided: np.ndarray) -> Observer:
    obs = Observer(values.size, np.zeros(1, dtype=bool), np.zeros(1, dtype=bool))
    obs.values, obs.decided = values, decided
    return obs


def test_same_seed_same_estimates() -> None:
    first = simulate(_loop(), _props(), runs=500, seed=3)
    again = simulate(_loop(), _props(), runs=500, seed=3)
    other = simulate(_loop(), _props(), runs=500, seed=4)
    assert [e.estimate for e in first.estimates] == [e.estimate for e in again.estimates]
    assert [e.estimate for e in first.estimates] != [e.estimate for e in other.estimates]


def test_sampler_follows_the_row_distribution() -> None:
    chain = _loop()
    sampler = _Sampler(chain)
    draws = sampler.step(np.zeros(200_000, dtype=np.int64), np.random.default_rng(1))
    freq = np.bincount(draws, minlength=4) / draws.size
    # 4.5 standard errors at most (sd of a frequency <= 0.5/sqrt(n) ~ 0.0011).
    assert freq == pytest.approx([0.0, 0.5, 0.3, 0.2], abs=0.005)


def test_a_wrong_exact_value_is_flagged() -> None:
    sim = simulate(_loop(), _props()[:1], runs=5_000, seed=0,
                   exact={'P=? [ F "bad" ]': 0.5})
    assert sim.estimates[0].disagrees
    assert any("outside the 99.9 % interval" in w for w in sim.warnings())


def test_undecided_runs_are_reported_not_dropped() -> None:
    # A slow random walk: few runs reach the end within 5 steps.
    walk = {s: {s + 1: 0.5, max(s - 1, 0): 0.5} for s in range(10)}
    chain = dtmc(walk, 11, labels={"end": [10]})
    sim = simulate(chain, [parse_property('P=? [ F "end" ]')], runs=200, seed=0, max_steps=5)
    (e,) = sim.estimates
    assert e.undecided == 200 and e.runs == 0 and math.isnan(e.estimate)
    assert "200 of 200 runs undecided after 5 steps" in sim.warnings()[0]


def test_reward_is_infinite_on_runs_that_cannot_reach_the_target() -> None:
    chain = _loop()  # R[F "bad"]: runs absorbed in "good" never reach "bad"
    prop = parse_property('R{"r"}=? [ F "bad" ]')
    assert check(chain, prop).value == math.inf
    sim = simulate(chain, [prop], runs=100, seed=0, exact={prop.text: math.inf})
    assert sim.estimates[0].estimate == math.inf and not sim.estimates[0].disagrees


def test_unsupported_properties_are_skipped_with_a_reason() -> None:
    sim = simulate(_loop(), [parse_property('P>0.5 [ F "bad" ]')], runs=10)
    assert sim.estimates == () and "not simulated" in sim.skipped[0]


def test_bad_counts_are_errors() -> None:
    with pytest.raises(CheckError, match="--runs must be at least 1"):
        simulate(_loop(), _props(), runs=0)
    with pytest.raises(CheckError, match="--max-steps must be at least 1"):
        simulate(_loop(), _props(), runs=1, max_steps=0)


def test_path_table_has_prism_simulator_columns() -> None:
    chain = _loop()
    sim = simulate(chain, _props()[:1], runs=3, seed=0, record=2)
    header, rows = path_table(chain, sim.paths)
    assert header == ["run", "action", "step", "s", "r"]
    assert {r[0] for r in rows} == {1, 2}
    for run in (1, 2):
        steps = [r for r in rows if r[0] == run]
        assert [r[2] for r in steps] == list(range(len(steps)))
        assert steps[0][3] == 0 and steps[-1][3] in (2, 3)  # from the start to absorption
        assert steps[-1][1] == ""


def test_path_table_names_a_reward_apart_from_its_variable() -> None:
    chain = build_dtmc(flatten_model(parse_model(
        "dtmc\nmodule m\n  rc : [0..1] init 0;\n  [] rc=0 -> (rc'=1);\n  [] rc=1 -> true;\n"
        "endmodule\nrewards \"rc\" rc=0 : 1; endrewards\n")))
    sim = simulate(chain, [parse_property('P=? [ F rc=1 ]')], runs=1, seed=0, record=1)
    header, rows = path_table(chain, sim.paths)
    assert header == ["run", "action", "step", "rc", "reward_rc"]
    assert [row[3:] for row in rows] == [[0, 1.0], [1, 0.0]]


def test_a_skipped_property_is_named_in_the_property_language() -> None:
    prop = parse_property('R{"r"}=? [ F "bad" || F "good" ]')
    sim = simulate(_loop(), [prop], runs=10)
    assert sim.estimates == ()
    assert "a conditional expectation (F a || F b) is not simulated" in sim.skipped[0]
    assert "ConditionalReach" not in sim.skipped[0]


@pytest.mark.parametrize(("text", "says"), [
    ('P=? [ G F "good" ]', "an LTL formula (a finite run cannot settle most) is not simulated"),
    ('R{"r"}=? [ F ("good" & (X "good")) ]',
     "a reward until a co-safe LTL formula holds is not simulated"),
])
def test_ltl_is_named_when_it_is_skipped(text: str, says: str) -> None:
    sim = simulate(_loop(), [parse_property(text)], runs=10)
    assert sim.estimates == () and says in sim.skipped[0]
