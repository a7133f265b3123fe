"""Differential: the checker against Storm's exact engine on the same PRISM models.

Storm builds each model with exact rational arithmetic; the test converts that
model into a veribattery DTMC (same state numbering) and compares every state's
value with Storm's exact answer within 1e-8 relative. Formulas are given twice:
as Storm property text and as our AST (the PRISM parser is not needed here).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import scipy.sparse as sp

from veribattery.checker import values
from veribattery.checker.certify.bounds import Bounds
from veribattery.explore.dtmc import DTMC, RewardVectors
from veribattery.lang.nodes import (
    Binary,
    Cumulative,
    DoubleLit,
    Eventually,
    Expr,
    Globally,
    Instantaneous,
    IntLit,
    LabelRef,
    Next,
    ProbOp,
    Reach,
    RewardOp,
    TimeBound,
    Unary,
    Until,
)

stormpy = pytest.importorskip("stormpy")

MODELS = Path(__file__).parent / "storm"
REL = 1e-8


@dataclass(frozen=True)
class Case:
    """One property on one model: Storm's text and our formula."""

    model: str
    storm: str
    formula: Expr

    def __str__(self) -> str:
        return f"{self.model}: {self.storm}"


def L(name: str) -> LabelRef:
    return LabelRef(name)


def Pq(path: Any) -> ProbOp:
    return ProbOp("=?", None, path)


def Rq(reward: str, path: Any) -> RewardOp:
    return RewardOp(reward, "=?", None, path)


def upto(k: int, op: str = "<=") -> TimeBound:
    return TimeBound(op, IntLit(k))  # type: ignore[arg-type]


CASES = [
    Case("die", 'P=? [F "one"]', Pq(Eventually(L("one")))),
    Case("die", 'P=? [F "six"]', Pq(Eventually(L("six")))),
    Case("die", 'P=? [!"left" U "done"]', Pq(Until(Unary("!", L("left")), L("done")))),
    Case("die", 'P=? [F<=3 "one"]', Pq(Eventually(L("one"), upto(3)))),
    Case("die", 'P=? [true U<5 "six"]', Pq(Eventually(L("six"), upto(5, "<")))),
    Case("die", 'P=? [X "left"]', Pq(Next(L("left")))),
    Case("die", 'P=? [G !"one"]', Pq(Globally(Unary("!", L("one"))))),
    Case("die", 'R{"coin_flips"}=? [F "done"]', Rq("coin_flips", Reach(L("done")))),
    Case("die", 'R{"coin_flips"}=? [F "one"]', Rq("coin_flips", Reach(L("one")))),
    Case("die", 'R{"coin_flips"}=? [C<=4]', Rq("coin_flips", Cumulative(IntLit(4)))),
    Case("die", 'R{"pips"}=? [I=6]', Rq("pips", Instantaneous(IntLit(6)))),
    Case("die", 'R{"pips"}=? [C<=10]', Rq("pips", Cumulative(IntLit(10)))),
    Case("die", 'P>=0.2 [F "one"] | "done"',
         Binary("|", ProbOp(">=", DoubleLit(0.2), Eventually(L("one"))), L("done"))),
    Case("ruin", 'P=? [F "win"]', Pq(Eventually(L("win")))),
    Case("ruin", 'P=? [!"low" U "win"]', Pq(Until(Unary("!", L("low")), L("win")))),
    Case("ruin", 'P=? [F<=100 "win"]', Pq(Eventually(L("win"), upto(100)))),
    Case("ruin", 'R{"steps"}=? [F "end"]', Rq("steps", Reach(L("end")))),
    Case("ruin", 'R{"steps"}=? [F "win"]', Rq("steps", Reach(L("win")))),
    Case("ruin", 'R{"steps"}=? [I=30]', Rq("steps", Instantaneous(IntLit(30)))),
    Case("battery", 'P=? [!"failed" U "full"]', Pq(Until(Unary("!", L("failed")), L("full")))),
    Case("battery", 'P=? [F "failed"]', Pq(Eventually(L("failed")))),
    Case("battery", 'P=? [F<=10 "empty"]', Pq(Eventually(L("empty"), upto(10)))),
    Case("battery", 'P=? [!"charging" U<=15 "empty"]',
         Pq(Until(Unary("!", L("charging")), L("empty"), upto(15)))),
    Case("battery", 'P=? [G !"empty"]', Pq(Globally(Unary("!", L("empty"))))),
    Case("battery", 'R{"energy"}=? [C<=20]', Rq("energy", Cumulative(IntLit(20)))),
    Case("battery", 'R{"energy"}=? [I=7]', Rq("energy", Instantaneous(IntLit(7)))),
    Case("battery", 'R{"time"}=? [F "failed"]', Rq("time", Reach(L("failed")))),
    Case("battery", 'R{"energy"}=? [F "failed"]', Rq("energy", Reach(L("failed")))),
    Case("battery", 'R{"energy"}=? [F "empty"]', Rq("energy", Reach(L("empty")))),
    Case("battery", 'P>=0.5 [F<=10 "empty"] & !"failed"',
         Binary("&", ProbOp(">=", DoubleLit(0.5), Eventually(L("empty"), upto(10))),
                Unary("!", L("failed")))),
    # Storm has no =>: its text spells out the implication our AST keeps.
    Case("battery", '!P<0.7 [F<=20 "failed"] | P>0.1 [X "charging"]',
         Binary("=>", ProbOp("<", DoubleLit(0.7), Eventually(L("failed"), upto(20))),
                ProbOp(">", DoubleLit(0.1), Next(L("charging"))))),
]


def _bits(vector: Any, n: int) -> np.ndarray:
    result = np.zeros(n, dtype=bool)
    result[list(vector)] = True
    return result


def _rewards(model: Any) -> tuple[RewardVectors, ...]:
    structures = []
    for name, rm in model.reward_models.items():
        state = [float(r) for r in rm.state_rewards] if rm.has_state_rewards else 0.0
        action = [float(r) for r in rm.state_action_rewards] if rm.has_state_action_rewards else 0.0
        zeros = np.zeros(model.nr_states)
        structures.append(RewardVectors(name, zeros + state, zeros + action))
    return tuple(structures)


def _to_dtmc(model: Any) -> DTMC:
    """Our DTMC with Storm's state numbering, probabilities rounded once to float64."""
    n = model.nr_states
    src, dst, prob = [], [], []
    for s in range(n):
        for entry in model.transition_matrix.get_row(s):
            src.append(s)
            dst.append(entry.column)
            prob.append(float(entry.value))
    P = sp.csr_matrix((prob, (src, dst)), shape=(n, n))
    labels = {name: _bits(model.labeling.get_states(name), n)
              for name in model.labeling.get_labels()}
    initial = np.asarray(list(model.initial_states), dtype=np.int64)
    return DTMC(P, np.zeros((n, 0), dtype=np.int64), (), initial, labels, _rewards(model))


_BUILT: dict[str, tuple[Any, Any, DTMC]] = {}


def _model(name: str) -> tuple[Any, Any, DTMC]:
    """Parse and build once per model, with every property of that model registered."""
    if name not in _BUILT:
        program = stormpy.parse_prism_program(str(MODELS / f"{name}.prism"))
        texts = "; ".join(c.storm for c in CASES if c.model == name)
        properties = stormpy.parse_properties(texts, program)
        model = stormpy.build_model[stormpy.Rational](program, properties)
        _BUILT[name] = (program, model, _to_dtmc(model))
    return _BUILT[name]


def _storm_values(case: Case, n: int) -> np.ndarray:
    program, model, _ = _model(case.model)
    prop = stormpy.parse_properties(case.storm, program)[0]
    result = stormpy.model_checking(model, prop, environment=stormpy.environments.exact())
    if result.is_qualitative():
        return _bits(result.get_truth_values_vector(), n)
    return np.array([float(result.get_value(s)) for s in range(n)])


@pytest.mark.parametrize("case", CASES, ids=str)
def test_matches_storm_exact(case: Case) -> None:
    dtmc = _model(case.model)[2]
    expected = _storm_values(case, dtmc.num_states)
    found = values(dtmc, case.formula)
    if isinstance(found, Bounds):
        # Storm's exact value, rounded to the nearest float, lies in the certified interval.
        assert np.all(found.lower <= expected) and np.all(expected <= found.upper)
        found = found.value
    ours = found
    assert ours.dtype == expected.dtype
    if expected.dtype == np.bool_:
        assert ours.tolist() == expected.tolist()
        return
    assert np.array_equal(np.isinf(ours), np.isinf(expected))
    finite = np.isfinite(expected)
    assert ours[finite].tolist() == pytest.approx(expected[finite].tolist(), rel=REL, abs=1e-300)


def test_state_counts_match() -> None:
    for name, states, transitions in (("die", 13, 20), ("ruin", 61, 120)):
        dtmc = _model(name)[2]
        assert (dtmc.num_states, dtmc.num_transitions) == (states, transitions)
