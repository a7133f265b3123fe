"""The Pareto front of a small mission MDP from Storm's multi-objective queries, with
BS1's points (veribattery's own DTMC check), as a figure and a CSV.

The farm: two cells (4 turbines at the base, 2 one cell away), 8 Ah, 8 recharges, gusty
wind (p_wsp_c 0.3). Storm's multi-objective precision is set to 1e-6 (its default, 1e-4,
leaves the answers 0.2% above the front here).
"""

from __future__ import annotations

import csv
import itertools
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest

from veribattery.config import load_config
from veribattery.render import render_synthesis_model
from veribattery.synthesis.bs1_values import bs1_points
from veribattery.synthesis.pareto import FrontPoint, write_pareto_csv, write_pareto_figure

stormpy = pytest.importorskip("stormpy")

from tests.synthesis.storm_strategy import StormMdp  # noqa: E402

FARM = ("farm.cols=3", "farm.rows=2", "farm.base=[0,0]", "battery.capacity_ah=8",
        "battery.max_recharges=8", "environment.p_wsp_c=0.3")
REQUIRED = (0.1, 0.2, 0.3, 0.5, 0.7, 0.8, 0.85)
#: A failed mission "costs" this many minutes: more than any minute a safer strategy
#: takes per unit of P(success) here, so the cheapest strategy is the safest.
FAILURE_MINUTES = 1000
_MINUTES = {"wait": "T_WAIT", "takeoff": "T_TL", "land": "T_TL", "fly": "T_CELL*dist",
            "back": "T_CELL*dist", "backnext": "T_CELL*dist", "next": "T_CELL*step",
            "inspect": "T_INS", "recharge": "T_RECHARGE"}


class _Mdp:
    """Storm's model of the farm's MDP, with a "cost" reward: minutes, and
    FAILURE_MINUTES per failed mission (abort or the recharge cap)."""

    def __init__(self, folder: Path) -> None:
        lines = [f"  [{a}] true : {m};" for a, m in _MINUTES.items()]
        lines += [f"  [{a}] true : {FAILURE_MINUTES};" for a in ("abort", "oob")]
        cost = "\n".join(['rewards "cost"', *lines, "endrewards", ""])
        text = render_synthesis_model(load_config("", FARM)) + "\n" + cost
        mdp = StormMdp.build(text, folder)
        self.model, self.program = mdp.model, mdp.program
        self.env = stormpy.Environment()
        self.env.modelchecker().multi().precision = stormpy.Rational("1/1000000")

    def value(self, formula: str, model: Any = None) -> Any:
        model = model or self.model
        prop = stormpy.parse_properties(formula, self.program)[0]
        result = stormpy.model_checking(model, prop, environment=self.env)
        init = model.initial_states[0]
        return (result.get_truth_values_vector()[init] if result.is_qualitative()
                else result.get_value(init))

    def fastest(self, p: float) -> Any:
        return self.value(f'multi(R{{"mt"}}min=? [ C ], P>={p!r} [ F "success" ])')

    def cheapest(self) -> tuple[float, float]:
        """P(success) and expected minutes of the strategy of least expected cost."""
        prop = stormpy.parse_properties('R{"cost"}min=? [ F "done" ]', self.program)[0]
        result = stormpy.model_checking(self.model, prop, extract_scheduler=True)
        induced = self.model.apply_scheduler(result.get_scheduler(), True)
        return (self.value('P=? [ F "success" ]', induced),
                self.value('R{"mt"}=? [ F "done" ]', induced))


def test_pareto_front_in_storm(tmp_path: Path) -> None:
    mdp = _Mdp(tmp_path)
    p_max = mdp.value('Pmax=? [ F "success" ]')
    front = [FrontPoint(p, float(mdp.fastest(p))) for p in (*REQUIRED, p_max)]
    assert 0.85 < p_max < 0.9 and mdp.fastest(0.9) is False
    times = [pt.exp_mission_time for pt in front]
    # Safer costs time, and ever more: the front is increasing and convex (randomising
    # between two strategies gives every point between them).
    assert all(a < b for a, b in itertools.pairwise(times))
    slopes = [(b.exp_mission_time - a.exp_mission_time) / (b.p - a.p)
              for a, b in itertools.pairwise(front)]
    assert all(a <= b * (1 + 1e-6) for a, b in itertools.pairwise(slopes))
    # The cheapest strategy when a failure costs 1000 minutes is a safest one, and no
    # strategy that safe is faster: it is the front's last point.
    p_cheap, t_cheap = mdp.cheapest()
    assert p_cheap == pytest.approx(p_max, rel=1e-9)
    assert times[-1] == pytest.approx(t_cheap, rel=1e-6)
    # BS1 is a strategy of the MDP: none of its points lies left of the front.
    bs1 = bs1_points(load_config("", FARM), [Fraction(1, 20), Fraction(3, 10)])
    assert [round(pt.p_success, 4) for pt in bs1] == [0.7998, 0.2346]
    for point in bs1:
        assert point.p_success <= p_max
        assert all(pt.exp_mission_time <= point.exp_mission_time
                   for pt in front if pt.p <= point.p_success)
    figure = write_pareto_figure(tmp_path / "front.png", front, bs1, p_max=p_max)
    assert figure.read_bytes().startswith(b"\x89PNG")
    write_pareto_csv(tmp_path / "front.csv", front, bs1)
    with (tmp_path / "front.csv").open(newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    assert [float(r["exp_mission_time"]) for r in rows if r["series"] == "front"] == times
    assert [r["safe_t"] for r in rows if r["series"] == "bs1"] == ["0.05", "0.3"]


def test_our_front_gives_storms_answers(tmp_path: Path) -> None:
    """veribattery's certified answers (weighted sums) at Storm's p: the same least
    times to Storm's precision (1e-6), and its front through the same region."""
    from veribattery.synthesis.fastest import fastest, front, mission_front, required_at_least
    from veribattery.synthesis.model import mission_mdp

    storm = _Mdp(tmp_path)
    mdp = mission_mdp(load_config("", FARM))
    search = mission_front(mdp)
    for p in REQUIRED:
        answer = fastest(mdp, required_at_least(p), search)
        assert answer.certified and answer.time_bounds is not None
        theirs = float(storm.fastest(p))
        assert answer.exp_mission_time == pytest.approx(theirs, rel=1e-6)
        assert answer.time_bounds[0] <= theirs * (1 + 1e-6)  # Storm's is achievable
    vertices = front(search)
    assert vertices[-1].p == pytest.approx(float(storm.value('Pmax=? [ F "success" ]')),
                                           rel=1e-12)
    assert vertices[-1].exp_mission_time == pytest.approx(storm.cheapest()[1], rel=1e-6)
