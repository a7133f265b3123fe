"""The DTMC synthesize's strategy induces, as the mission analyses get it: the same chain
as the exported ``induced.prism`` built like any PRISM file, with the same values."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from veribattery._types import IntArray
from veribattery.checker.mdp import reach_probability
from veribattery.config import load_config
from veribattery.explore import DTMC, build_dtmc
from veribattery.lang import flatten_model, parse_model
from veribattery.synthesis.exports import StrategyExport, strategy_export_texts
from veribattery.synthesis.induced_dtmc import InducedMission, optimal_mission
from veribattery.synthesis.model import mission_model
from veribattery.synthesis.optimal import safest_fastest

CASE1 = Path(__file__).resolve().parents[2] / "configs" / "paper" / "case1.yaml"
FARM = ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=6",
        "battery.max_recharges=8")


@pytest.fixture(scope="module")
def induced() -> InducedMission:
    return optimal_mission(load_config(CASE1, FARM))


@pytest.fixture(scope="module")
def exported() -> DTMC:
    """The induced model synthesize --export-induced writes, built from its text."""
    flat, mdp = mission_model(load_config(CASE1, FARM))
    chosen = safest_fastest(mdp, reach_probability(mdp, mdp.labels["success"],
                                                   objective="max"))
    folder = Path("induced")
    text = strategy_export_texts(flat, mdp, chosen, StrategyExport(induced_dir=folder))
    return build_dtmc(flatten_model(parse_model(text[folder / "induced.prism"])))


def _order(dtmc: DTMC) -> IntArray:
    """The states sorted by valuation (the two chains number them differently)."""
    return np.lexsort(dtmc.states.T[::-1])


def test_the_chain_is_the_exported_one(induced: InducedMission, exported: DTMC) -> None:
    mine, theirs = induced.dtmc, exported
    assert mine.num_states == theirs.num_states == 707
    assert mine.variable_names == theirs.variable_names
    a, b = _order(mine), _order(theirs)
    np.testing.assert_array_equal(mine.states[a], theirs.states[b])
    difference = mine.transitions[a][:, a] - theirs.transitions[b][:, b]
    assert abs(difference).max() <= 1e-15
    assert int(np.flatnonzero(a == mine.initial[0])[0]) == int(
        np.flatnonzero(b == theirs.initial[0])[0])
    for name in ("success", "failure", "done"):
        np.testing.assert_array_equal(mine.labels[name][a], theirs.labels[name][b])
    for name in ("mt", "rc"):
        np.testing.assert_allclose(mine.reward(name).total[a], theirs.reward(name).total[b],
                                   rtol=0, atol=1e-12)


def test_its_values_are_the_strategys(induced: InducedMission) -> None:
    """P(success) and the expected rewards to "done", solved directly on the chain."""
    dtmc, own = induced.dtmc, induced.values
    done = dtmc.labels["done"]
    start = int(dtmc.initial[0])
    open_ = np.flatnonzero(~done)
    inner = sp.identity(open_.size, format="csc") - dtmc.transitions[open_][:, open_]
    into_success = np.asarray(dtmc.transitions[open_][:, dtmc.labels["success"]].sum(axis=1))
    p = spsolve(inner, into_success.ravel())
    where = int(np.flatnonzero(open_ == start)[0])
    assert p[where] == pytest.approx(own["p_success"], rel=1e-9)
    for name, value in (("mt", own["exp_mission_time"]), ("rc", own["exp_recharges"])):
        expected = spsolve(inner, dtmc.reward(name).total[open_])
        assert expected[where] == pytest.approx(value, rel=1e-9)


def test_each_state_names_the_action_taken(induced: InducedMission) -> None:
    dtmc, actions = induced.dtmc, induced.actions
    assert actions.shape == (dtmc.num_states,)
    assert actions[int(dtmc.initial[0])] == "takeoff"
    counts = dict(zip(*np.unique(actions, return_counts=True), strict=True))
    assert counts == {"recharge": 216, "land": 144, "": 68, "back": 64, "finish": 56,
                      "fly": 48, "inspect": 32, "takeoff": 24, "backnext": 24, "wait": 23,
                      "abort": 8}
    # Only the absorbing success (s=7) and failure (s=6) states take the unlabelled loop.
    assert set(dtmc.column("s")[actions == ""].tolist()) == {6, 7}
