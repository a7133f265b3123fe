"""Differential tests against Storm for the operators Storm has: S, R [S], R [C],
step intervals and exact step bounds on F and U, T, and filters (Storm's per-state
values reduced independently here), state by state.

Models: the hand-built periodic two-BSCC chain of ``test_pctl_language`` and the
PRISM peer suites' steady-state models.
"""

from __future__ import annotations

import math

import pytest

stormpy = pytest.importorskip("stormpy")

from tests.checker.test_pctl_language import MODEL  # noqa: E402
from tests.conftest import PEER_TESTS, require_shared  # noqa: E402
from tests.storm_oracle import compare, run_storm  # noqa: E402
from veribattery.pipeline import check_prism_file  # noqa: E402

RTOL, ATOL = 1e-8, 1e-12

PROPERTIES = [
    "S=? [ s=3 ]",
    "S=? [ s=1 | s=4 ]",
    'R{"r"}=? [ S ]',
    'R{"r"}=? [ C ]',
    "P=? [ F[3,3] s=2 ]",
    "P=? [ F[1,4] s=4 ]",
    "P=? [ F=2 s=3 ]",
    "P=? [ s<=2 U[1,3] s=3 ]",
    "T=? [ F s!=0 ]",
    "S>0.4 [ s=3 ]",
]


def test_operators_agree_with_storm_in_every_state() -> None:
    run = check_prism_file(MODEL, selectors=tuple(PROPERTIES))
    storm = run_storm(MODEL, ";".join(PROPERTIES), exact=True)
    assert compare(run, storm, PROPERTIES, rtol=RTOL, atol=ATOL) == []


@pytest.mark.parametrize(
    ("op", "reduce"),
    [("min", min), ("max", max), ("sum", math.fsum), ("avg", lambda v: math.fsum(v) / len(v))],
)
def test_filters_reduce_storms_values(op: str, reduce: object) -> None:
    inner = "S=? [ s=3 ]"
    storm = run_storm(MODEL, inner, exact=True)
    chosen = [v for val, v in zip(storm.valuations, storm.values[0], strict=True)
              if val["s"] >= 1]
    run = check_prism_file(MODEL, selectors=(f"filter({op}, {inner}, s>=1)",))
    assert run.results[0].value == pytest.approx(reduce(chosen), rel=RTOL)  # type: ignore[operator]


STEADY_MODELS = [
    ("functionality/verify/dtmcs/dtmc_steady_1.pm", "S=? [ s=1 & t=0 ];S=? [ t=1 ]"),
    ("functionality/verify/multiple_bsccs_ss.pm", "S=? [ s=3 ];S=? [ s=5 ]"),
    ("functionality/verify/dtmcs/rewards/dtmc_rewards_bsccs.pm",
     'R{"a"}=? [ C ];R{"b"}=? [ C ];R{"c"}=? [ S ]'),
    ("contrib/garavel/HG-13.pm", "S=? [ x!=y ];S=? [ x=z & x!=y ]"),
]


@pytest.mark.parametrize(("model", "props"), STEADY_MODELS, ids=[m for m, _ in STEADY_MODELS])
def test_peer_models_agree_with_storm(model: str, props: str) -> None:
    require_shared()
    path = PEER_TESTS / "prism-extended" / "prism-tests" / model
    labels = props.split(";")
    run = check_prism_file(path, selectors=tuple(labels))
    storm = run_storm(path, props, exact=False)
    assert compare(run, storm, labels, rtol=1e-6, atol=1e-9) == []
