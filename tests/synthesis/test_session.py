"""``synthesize(cfg)``: the values of veribattery's own MDP engine against Storm on the
emitted MDP, the strategy it reports against a direct solve of its own chain, and the
spec's inclusion (BS1 is one strategy of the MDP) over the paper's four cases on a small
farm and a short capacity sweep.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from veribattery.config import MissionConfig, load_config
from veribattery.render import render_synthesis_model
from veribattery.synthesis.bs1_values import bs1_values
from veribattery.synthesis.fastest import LP_TOLERANCE, fastest, required_at_least
from veribattery.synthesis.model import mission_mdp
from veribattery.synthesis.optimal import safest_fastest
from veribattery.synthesis.session import FrontRequest, synthesize

REPO = Path(__file__).resolve().parents[2]
CASES = [REPO / "configs" / "paper" / f"case{i}.yaml" for i in range(1, 5)]
#: Six cells (3 x 2 turbines, base at a corner), 6 Ah, 8 recharges: 1,431 states for case 1.
FARM = ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=6",
        "battery.max_recharges=8")
#: How far a linear programme's time may lie off the optimum, relative (HiGHS's
#: feasibility tolerance, times a margin for the objective's conditioning).
LP_RELATIVE = 1e-5


def _config(case: Path, *extra: str) -> MissionConfig:
    return load_config(case, [*FARM, *extra])


def _storm(cfg: MissionConfig, folder: Path) -> tuple[object, object, object]:
    stormpy = pytest.importorskip("stormpy")
    path = folder / "model.prism"
    path.write_text(render_synthesis_model(cfg))
    program = stormpy.parse_prism_program(str(path))
    options = stormpy.BuilderOptions()
    options.set_build_all_labels()
    options.set_build_all_reward_models()
    model = stormpy.build_model(program, options=options)
    env = stormpy.Environment()
    env.modelchecker().multi().precision = stormpy.Rational("1/100000000")
    return stormpy, program, (model, env)


def _storm_value(cfg: MissionConfig, folder: Path, formula: str) -> float:
    stormpy, program, (model, env) = _storm(cfg, folder)
    prop = stormpy.parse_properties(formula, program)[0]  # type: ignore[attr-defined]
    result = stormpy.model_checking(model, prop, environment=env)  # type: ignore[attr-defined]
    return float(result.get_value(model.initial_states[0]))  # type: ignore[attr-defined]


@pytest.mark.parametrize("case", [CASES[0], CASES[3]], ids=["case1", "case4"])
def test_values_equal_storms_on_the_emitted_mdp(case: Path, tmp_path: Path) -> None:
    cfg = _config(case)
    result = synthesize(cfg, [required_at_least(0.9), required_at_least(0.5)])
    storm_states = _storm(cfg, tmp_path)[2][0].nr_states  # type: ignore[index]
    assert result.size.states == storm_states
    pmax = _storm_value(cfg, tmp_path, 'Pmax=? [ F "success" ]')
    assert result.p_success_max.lower <= pmax * (1 + 1e-12) + 1e-15
    assert result.p_success_max.upper >= pmax * (1 - 1e-12) - 1e-15
    assert result.p_success_max.value == pytest.approx(pmax, rel=1e-9)
    for answer in result.fastest:
        if answer.p > pmax:
            assert not answer.achievable
            continue
        storm = _storm_value(cfg, tmp_path,
                             f'multi(R{{"mt"}}min=? [ C ], P>={answer.p!r} [ F "success" ])')
        assert answer.achievable and answer.certified and answer.time_bounds is not None
        # Storm's precision is 1e-8 (relative); the certified interval holds its value
        low, high = answer.time_bounds
        assert low * (1 - 1e-8) <= storm <= high * (1 + 1e-8)
        assert answer.exp_mission_time == pytest.approx(storm, rel=1e-8)


def test_a_requirement_above_pmax_is_not_met(tmp_path: Path) -> None:
    cfg = _config(CASES[2])
    result = synthesize(cfg, [required_at_least(0.999)])
    assert result.p_success_max.value < 0.999
    (answer,) = result.fastest
    assert not answer.achievable and answer.exp_mission_time is None
    assert answer.certified  # above Pmax's certified interval: no programme needed
    assert not result.all_requirements_met
    # The LP agrees that no strategy meets it.
    assert not fastest(mission_mdp(cfg), required_at_least(0.999)).achievable


def test_a_requirement_at_pmax_is_the_tabulated_strategy() -> None:
    cfg = _config(CASES[0])
    pmax = synthesize(cfg).p_success_max.value
    result = synthesize(cfg, [required_at_least(pmax)], as_safe_as_bs1=True)
    at_pmax, as_bs1 = result.fastest
    assert at_pmax.certified and at_pmax.achievable
    assert at_pmax.exp_mission_time == result.strategy.exp_mission_time.value
    assert at_pmax.exp_recharges == result.strategy.exp_recharges.value
    assert as_bs1.p == result.bs1.p_success.value < pmax and as_bs1.certified


def test_the_fronts_answers_agree_with_the_linear_programmes() -> None:
    """On the 3 x 2 farm: the least time (certified) holds the programme's value, and
    the recharges of the strategy found are no fewer than the programme's fewest
    among the strategies that fast."""
    from veribattery.checker.mdp import Constraint, Reach, Total, multi_optimum

    cfg = _config(CASES[0])
    mdp = mission_mdp(cfg)
    success = Reach(mdp.labels["success"])
    time = Total(mdp.reward("mt").per_choice(mdp))
    recharges = Total(mdp.reward("rc").per_choice(mdp))
    for p in (0.5, 0.9, bs1_values(cfg).p_success.value):
        answer = fastest(mdp, required_at_least(p))
        assert answer.certified and answer.time_bounds is not None
        assert answer.recharges_bounds is not None and answer.exp_recharges is not None
        meets = Constraint(success, ">=", p)
        lp = multi_optimum(mdp, time, "min", [meets]).value
        assert lp is not None
        low, high = answer.time_bounds
        assert low - LP_RELATIVE * lp <= lp <= high + LP_RELATIVE * lp
        assert high - low <= 1e-9 * high
        fewest = multi_optimum(mdp, recharges, "min", [
            meets, Constraint(time, "<=", high * (1 + 1e-9))]).value
        assert fewest is not None
        assert answer.recharges_bounds[1] >= fewest * (1 - LP_RELATIVE)


def _chain_values(cfg: MissionConfig) -> tuple[object, object, float, float, float]:
    """The strategy's values, and P(success), E[mt], E[rc] of its chain solved directly
    (a sparse linear system, outside the MDP engine)."""
    mdp = mission_mdp(cfg)
    from veribattery.checker.mdp import reach_probability

    chosen = safest_fastest(mdp, reach_probability(mdp, mdp.labels["success"],
                                                   objective="max"))
    chain = sp.csr_matrix(mdp.transitions[chosen.choices])
    done = mdp.labels["done"]
    moving = np.flatnonzero(~done)
    inner = sp.identity(moving.size, format="csr") - chain[moving][:, moving]
    start = int(np.searchsorted(moving, mdp.initial[0]))
    p = spsolve(inner.tocsc(), chain[moving] @ mdp.labels["success"].astype(float))
    values = []
    for name in ("mt", "rc"):
        reward = mdp.reward(name).per_choice(mdp)[chosen.choices][moving]
        values.append(float(spsolve(inner.tocsc(), reward)[start]))
    return chosen, mdp, float(p[start]), values[0], values[1]


@pytest.mark.parametrize("case", CASES, ids=[c.stem for c in CASES])
def test_the_tables_strategy_is_what_it_says(case: Path) -> None:
    chosen, _, p, time, recharges = _chain_values(_config(case))
    assert chosen.p_success.lower <= p * (1 + 1e-12) and p <= chosen.p_success.upper * (
        1 + 1e-12)
    assert chosen.exp_mission_time.value == pytest.approx(time, rel=1e-9)
    assert chosen.exp_recharges.value == pytest.approx(recharges, rel=1e-9)


POINTS = [(case, ()) for case in CASES] + [
    (CASES[0], (f"battery.capacity_ah={c}",)) for c in (5, 7, 8)]


@pytest.mark.parametrize(("case", "extra"), POINTS,
                         ids=[f"{c.stem}{'-' + e[0].split('=')[1] + 'Ah' if e else ''}"
                              for c, e in POINTS])
def test_bs1_is_one_strategy_of_the_mdp(case: Path, extra: tuple[str, ...]) -> None:
    """P_BS1 <= Pmax, and for p <= P_BS1 the fastest strategy is no slower than BS1."""
    cfg = _config(case, *extra)
    mdp = mission_mdp(cfg)
    from veribattery.checker.mdp import reach_probability

    pmax = reach_probability(mdp, mdp.labels["success"], objective="max")
    bs1 = bs1_values(cfg)
    assert bs1.p_success.lower <= pmax.upper[mdp.initial[0]]
    for p in (bs1.p_success.value, bs1.p_success.value / 2):
        answer = fastest(mdp, required_at_least(p))
        assert answer.achievable and answer.exp_mission_time is not None
        slack = LP_RELATIVE * bs1.exp_mission_time.value + LP_TOLERANCE
        assert answer.exp_mission_time <= bs1.exp_mission_time.upper + slack
        assert answer.exp_recharges is not None


def test_the_front_rises_to_pmax_and_bs1_lies_right_of_it() -> None:
    cfg = _config(CASES[2])
    result = synthesize(cfg, front_request=FrontRequest())
    ps = [point.p for point in result.front]
    times = [point.exp_mission_time for point in result.front]
    assert len(ps) >= 3 and ps == sorted(ps) and times == sorted(times)
    assert ps[-1] == pytest.approx(result.p_success_max.value, abs=1e-12)
    # convex: the slopes between neighbouring vertices increase
    pairs = zip(zip(ps, times, strict=True), zip(ps[1:], times[1:], strict=True), strict=False)
    slopes = [(t1 - t0) / (p1 - p0) for (p0, t0), (p1, t1) in pairs]
    assert slopes == sorted(slopes)
    assert [b.safe_t for b in result.bs1_front] == sorted({*FrontRequest().safe_ts,
                                                          cfg.strategy.safe_t})
    for bs1 in result.bs1_front:
        if bs1.p_success <= ps[0]:
            assert times[0] <= bs1.exp_mission_time * (1 + 1e-9)
            continue
        i = max(i for i, p in enumerate(ps) if p <= bs1.p_success)
        if i + 1 == len(ps):
            continue
        w = (bs1.p_success - ps[i]) / (ps[i + 1] - ps[i])
        assert times[i] + w * (times[i + 1] - times[i]) <= bs1.exp_mission_time * (1 + 1e-9)


def test_a_requirement_must_be_a_probability() -> None:
    from veribattery.errors import OptionError

    with pytest.raises(OptionError, match=r"--require 1\.5: not a probability"):
        required_at_least(1.5)
    assert required_at_least(0.99).requirement == "p_success >= 0.99"


@pytest.mark.parametrize("case", [CASES[0], CASES[2]], ids=["case1", "case3"])
def test_the_fastest_at_pmax_is_the_tabulated_strategy(case: Path) -> None:
    """Two methods, one answer: the linear programme at P(success) >= Pmax (less the
    programme's tolerance) and the certified safest-then-fastest strategy."""
    cfg = _config(case)
    result = synthesize(cfg)
    near_pmax = result.p_success_max.value - LP_TOLERANCE
    answer = fastest(mission_mdp(cfg), required_at_least(near_pmax))
    assert answer.exp_mission_time is not None
    assert answer.exp_mission_time <= result.strategy.exp_mission_time.upper * (1 + 1e-9)
    assert answer.exp_mission_time == pytest.approx(result.strategy.exp_mission_time.value,
                                                    rel=1e-5)
