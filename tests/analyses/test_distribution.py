"""The mission-time distribution: against the backward kernel and Storm at several T,
closed forms, a Monte-Carlo sampler (99.9 % intervals), deadlines, and the CLI."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from tests.checker.chains import dtmc
from tests.checker.test_conditional import CHAIN, REPO, SMALL_MISSION
from veribattery.analyses.distribution import (
    parse_deadline,
    plot_distribution,
    reward_distribution,
    write_csv,
)
from veribattery.checker import Workspace
from veribattery.checker.kernels.reward_bounded import integer_levels, reward_bounded_until_probs
from veribattery.cli import cli
from veribattery.errors import CheckError, ConfigError
from veribattery.explore.dtmc import DTMC
from veribattery.lang import parse_model
from veribattery.pipeline import check_model

MISSION_ARGS = [str(REPO / "configs/paper/case3.yaml"),
                *(arg for key in SMALL_MISSION for arg in ("--set", key))]


def _chain() -> DTMC:
    return check_model(parse_model(CHAIN, name="chain"), ()).dtmc


@pytest.fixture(scope="module")
def mission() -> DTMC:
    from veribattery.config import load_config
    from veribattery.mission import mission_dtmc

    return mission_dtmc(load_config(REPO / "configs/paper/case3.yaml", SMALL_MISSION))


def test_every_level_agrees_with_the_backward_kernel(mission: DTMC) -> None:
    dist = reward_distribution(mission, coverage=1.0, horizon=400)
    levels = integer_levels(mission.reward("mt").total)
    everywhere = np.ones(mission.num_states, dtype=bool)
    start = int(mission.initial[0])
    for label, cdf in (("success", dist.success_cdf), ("failure", dist.failure_cdf)):
        for t in range(0, 401, 7):
            kernel = reward_bounded_until_probs(mission.transitions, everywhere,
                                                mission.labels[label], levels, t,
                                                workspace=Workspace())[start]
            # The pass stops once nothing is under way, which may be short of the horizon:
            # past the last level the CDF stays at its last value.
            assert cdf[min(t, cdf.size - 1)] == pytest.approx(kernel, abs=1e-13), (label, t)
    assert dist.p_success == pytest.approx(0.406, abs=1e-12)
    assert dist.success_cdf[-1] + dist.failure_cdf[-1] + dist.pending == pytest.approx(1.0)


def test_against_storm_at_several_deadlines(mission: DTMC, tmp_path: Path) -> None:
    from tests.checker.test_reward_bounded import _storm
    from veribattery.config import load_config
    from veribattery.render import render_model

    text = render_model(load_config(REPO / "configs/paper/case3.yaml", SMALL_MISSION))
    bounds = (150, 236, 246, 247, 300)
    props = [f'P=? [ F{{"mt"}}<={t} "{label}" ]' for t in bounds
             for label in ("success", "failure")]
    storm = _storm(text, props, tmp_path)
    dist = reward_distribution(mission, horizon=max(bounds))
    ours = [dist.p_success_within(t) if label == "success"
            else float(dist.failure_cdf[min(t, dist.failure_cdf.size - 1)])  # see above
            for t in bounds for label in ("success", "failure")]
    assert ours == pytest.approx(storm, rel=1e-8, abs=1e-12)
    assert any(0 < v < 1 for v in storm)


def test_zero_reward_loops_closed_form() -> None:
    # As in test_reward_bounded: P(goal within k) = 1 - (2/3)^k; failure never.
    chain = dtmc({0: {0: 0.5, 1: 0.5}, 1: {2: 1 / 3, 0: 2 / 3}}, 3,
                 labels={"success": [2], "failure": []},
                 rewards={"mt": ([0.0, 1.0, 0.0], [0.0, 0.0, 0.0])})
    dist = reward_distribution(chain, coverage=0.999999)
    k = np.arange(dist.values.size)
    assert dist.success_cdf == pytest.approx(1 - (2 / 3) ** k, abs=1e-13)
    assert dist.pending == pytest.approx((2 / 3) ** k[-1], rel=1e-9)
    # Number of s1 visits is geometric(1/3): mean 3; quantiles from 1-(2/3)^k >= q.
    assert dist.expected_given_success == pytest.approx(3.0, rel=1e-12)
    for q in (0.5, 0.9, 0.99):
        assert dist.quantile(q) == math.ceil(math.log(1 - q) / math.log(2 / 3))


def _sample(chain: DTMC, runs: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised Monte-Carlo: total reward and outcome (1 success, 2 failure) of each run."""
    rng = np.random.default_rng(seed)
    P = chain.transitions
    cumulative = [np.cumsum(P[s].toarray()[0]) for s in range(chain.num_states)]
    table = np.array(cumulative)
    reward = chain.reward("t").total
    success, failure = chain.labels["succ"], chain.labels["fail"]
    state = np.full(runs, int(chain.initial[0]))
    total = np.zeros(runs)
    moving = np.ones(runs, dtype=bool)
    while moving.any():
        idx = np.flatnonzero(moving)
        total[idx] += reward[state[idx]]
        u = rng.random(idx.size)
        state[idx] = (table[state[idx]] < u[:, None]).sum(axis=1)
        moving[idx] = ~(success[state[idx]] | failure[state[idx]])
    outcome = np.where(success[state], 1, 2)
    return total, outcome


def test_against_monte_carlo_within_its_99_9_percent_interval() -> None:
    chain = _chain()
    dist = reward_distribution(chain, "t", "succ", "fail", coverage=0.9999)
    total, outcome = _sample(chain, 20_000, seed=7)
    z = 3.2905  # two-sided 99.9 %
    for t in (5, 7, 10, 15, 25):
        for label, cdf, code in (("succ", dist.success_cdf, 1), ("fail", dist.failure_cdf, 2)):
            exact = float(cdf[t])
            estimate = float(np.mean((outcome == code) & (total <= t)))
            half = z * math.sqrt(max(exact * (1 - exact), 1e-12) / total.size)
            assert abs(estimate - exact) <= half, (label, t, estimate, exact)


def test_hand_values_of_the_chain() -> None:
    dist = reward_distribution(_chain(), "t", "succ", "fail")
    assert dist.success[:6].tolist() == pytest.approx([0, 0, 0, 0, 0, 0.3], abs=1e-15)
    assert dist.failure[3] == pytest.approx(0.15, abs=1e-15)  # 0 -> 2 -> 4: 2 + 1
    assert dist.expected_given_success == pytest.approx(22 / 3, rel=1e-12)
    assert dist.p_success == pytest.approx(0.5, abs=1e-12)


def test_errors() -> None:
    chain = _chain()
    with pytest.raises(CheckError, match='no reward structure "x"'):
        reward_distribution(chain, "x", "succ", "fail")
    with pytest.raises(CheckError, match='no label "success"'):
        reward_distribution(chain, "t")
    bad = check_model(parse_model(CHAIN.replace(": 3;", ": 0.5;"), name="c"), ()).dtmc
    with pytest.raises(CheckError, match="non-negative integer rewards"):
        reward_distribution(bad, "t", "succ", "fail")


@pytest.mark.parametrize(("text", "minutes"), [("4800", 4800), ("4800m", 4800), ("90min", 90),
                                               ("80h", 4800), ("5d", 2400), ("1.5h", 90),
                                               ("4.8e3", 4800), ("1e1h", 600)])
def test_deadlines(text: str, minutes: float) -> None:
    assert parse_deadline(text, working_day_minutes=480).value == minutes


@pytest.mark.parametrize(("text", "why"), [
    ("5x", "unknown unit 'x'"), ("d", "not a number"), ("", "not a number"),
    ("5 days", "unknown unit 'days'"), ("-3", "a time cannot be negative"),
    ("1e400", "a time cannot be beyond the largest number"), ("inf", "not a number"),
])
def test_bad_deadlines(text: str, why: str) -> None:
    with pytest.raises(ConfigError, match=f"--deadline '{text}': {why}"):
        parse_deadline(text)


def test_csv_and_plot(tmp_path: Path) -> None:
    dist = reward_distribution(_chain(), "t", "succ", "fail")
    csv = write_csv(dist, tmp_path / "d.csv")
    lines = csv.read_text().splitlines()
    assert lines[0] == "t,p_success,p_failure,cdf_success,cdf_failure"
    assert len(lines) == dist.values.size + 1
    png = plot_distribution(dist, [parse_deadline("10")], tmp_path / "d.png")
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_cli(tmp_path: Path) -> None:
    runner = CliRunner()
    csv, png = tmp_path / "d.csv", tmp_path / "d.png"
    result = runner.invoke(cli, ["distribution", *MISSION_ARGS, "--deadline", "4h",
                                 "--deadline", "1d", "--working-day", "250m", "-o", str(csv),
                                 "--plot", str(png), "--format", "json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["p_success"] == pytest.approx(0.406, abs=1e-12)
    assert [d["value"] for d in doc["deadlines"]] == [240, 250]
    assert doc["deadlines"][0]["p_success_within"] == 0.0
    assert doc["deadlines"][1]["p_success_within"] == pytest.approx(0.406, abs=1e-12)
    assert csv.exists() and png.exists()
    table = runner.invoke(cli, ["distribution", *MISSION_ARGS])
    assert table.exit_code == 0 and "E[mt | success]" in table.stdout


@pytest.mark.parametrize("args", [["--deadline", "5x"], ["--reward", "nope"],
                                  ["--working-day", "8y"], ["--coverage", "0"],
                                  ["--coverage", "-0.0"], ["--coverage", "nan"]])
def test_cli_bad_input(args: list[str]) -> None:
    result = CliRunner().invoke(cli, ["distribution", *MISSION_ARGS, *args])
    assert result.exit_code == 2
    assert "Traceback" not in result.output and len(result.stderr.strip().splitlines()) == 1


def test_cli_keeps_existing_files(tmp_path: Path) -> None:
    csv = tmp_path / "d.csv"
    csv.write_text("mine")
    result = CliRunner().invoke(cli, ["distribution", *MISSION_ARGS, "-o", str(csv)])
    assert result.exit_code == 2 and csv.read_text() == "mine"


@pytest.mark.parametrize("output_format", ["table", "json", "csv"])
def test_cli_when_success_is_unreachable(tmp_path: Path, output_format: str) -> None:
    """No recharge allowed: every mission fails. The quantiles and E[mt | success] are
    undefined: shown as such (and the plot drawn), not a CheckError traceback (exit 1)
    nor nan printed as a value."""
    png = tmp_path / "d.png"
    result = CliRunner().invoke(cli, ["distribution", *MISSION_ARGS, "--set",
                                      "battery.max_recharges=0", "--plot", str(png),
                                      "--format", output_format])
    assert result.exit_code == 0, (result.output, result.exception)
    assert "nan" not in result.stdout.lower() and png.exists()
    if output_format == "json":
        doc = json.loads(result.stdout)
        assert doc["p_success"] == 0 and doc["expected_given_success"] is None
        assert set(doc["quantiles"].values()) == {None}
    elif output_format == "csv":
        assert '"50% quantile of mt to success",\n' in result.stdout
    else:
        assert re.search(r"^50% quantile of mt to success +—$", result.stdout, re.M)
        assert "—: undefined: success is unreachable" in result.stdout


def test_a_far_deadline_stops_once_nothing_is_under_way() -> None:
    """A deadline of 10^8 minutes ran all of MAX_LEVELS (a million) empty levels, minutes
    on the paper's farm; the pass now stops once the pending mass is rounding noise."""
    result = CliRunner().invoke(cli, ["distribution", *MISSION_ARGS, "--deadline", "100000000",
                                      "--format", "json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["levels"] < 100_000 and doc["pending"] <= 1e-12
    (deadline,) = doc["deadlines"]
    assert deadline["p_success_within"] == pytest.approx(doc["p_success"], abs=1e-12)
