"""The strategy files agree with Storm's own scheduler, and the PRISM MDP corpus's
unbounded properties all export a strategy whose induced DTMC attains the optimum."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import require_shared
from tests.strategies.models import ROBOT
from veribattery.checker.mdp.witness import NoStrategyError
from veribattery.errors import VeribatteryError
from veribattery.pipeline import check_prism_file
from veribattery.pipeline.mdp import MdpCheckRun
from veribattery.strategies import (
    INDUCED_MODEL,
    INDUCED_PROPERTIES,
    choose_strategy,
    export_strategy,
    storm_scheduler_json,
)

stormpy = pytest.importorskip("stormpy")

#: Corpus entries with more states are left out (time, not principle).
MAX_CORPUS_STATES = 5000


def _storm_scheduler(model: Path, prop: str) -> list[dict[str, Any]]:
    """Storm's own optimal scheduler of *prop*, as its ``--exportscheduler`` JSON."""
    program = stormpy.parse_prism_program(str(model))
    formula = stormpy.parse_properties(prop, program)[0]
    options = stormpy.BuilderOptions([])
    options.set_build_state_valuations()
    options.set_build_choice_labels(True)
    options.set_build_all_labels()
    options.set_build_all_reward_models()
    built = stormpy.build_model[float](program, options=options)
    result = stormpy.model_checking(built, formula, extract_scheduler=True)
    return list(json.loads(result.get_scheduler().to_json_str(built)))


@pytest.mark.parametrize("prop", ['Pmax=? [ F "goal" ]', 'R{"steps"}min=? [ F "goal" ]'])
def test_storm_json_matches_storms_own_scheduler(tmp_path: Path, prop: str) -> None:
    """Each optimum here has one optimal action per state: east. Storm's scheduler,
    exported by Storm, says the same in the same shape (Storm lists every state)."""
    model = tmp_path / "robot.nm"
    model.write_text(ROBOT, encoding="utf-8")
    run = check_prism_file(model, selectors=(prop,), keep="answers")
    assert isinstance(run, MdpCheckRun)
    ours = json.loads(storm_scheduler_json(choose_strategy(run)))
    storms = {json.dumps(e["s"], sort_keys=True): e for e in _storm_scheduler(model, prop)}
    assert len(ours) == 4
    for entry in ours:
        storm = storms[json.dumps(entry["s"], sort_keys=True)]
        assert set(storm) == set(entry) == {"s", "c"}
        assert set(storm["c"][0]) == set(entry["c"][0]) == {"labels", "index", "prob"}
        assert entry["c"][0]["labels"] == storm["c"][0]["labels"]
        assert entry["c"][0]["prob"] == storm["c"][0]["prob"] == 1.0


def _corpus() -> list[dict[str, Any]]:
    """The prism-mdp suite's entries of unbounded Pmin/Pmax/Rmin/Rmax queries."""
    folder = require_shared() / "prism-mdp"
    entries = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))["entries"]
    return [e for e in entries
            if e.get("expected") != "error" and (e.get("states") or 0) <= MAX_CORPUS_STATES
            and e["property"].lstrip('"').startswith(("Pmin", "Pmax", "Rmin", "Rmax", "R{"))]


def test_every_corpus_optimum_is_attained_by_its_exported_strategy(tmp_path: Path) -> None:
    folder = require_shared() / "prism-mdp"
    confirmed, problems = 0, []
    for index, entry in enumerate(_corpus()):
        try:
            run = check_prism_file(folder / entry["model"], props_source=folder / entry["props"],
                                   selectors=(str(entry["property_index"]),),
                                   constants=entry["constants"], keep="answers")
        except VeribatteryError:  # not checked yet (multi-objective): nothing to export
            continue
        assert isinstance(run, MdpCheckRun)
        out = tmp_path / str(index)
        try:
            export_strategy(run, induced_dir=out)
        except NoStrategyError:  # step-bounded, filters: refused on purpose
            continue
        induced = check_prism_file(out / INDUCED_MODEL, props_source=out / INDUCED_PROPERTIES,
                                   keep="answers").results[0]
        want, got = float(run.results[0].value), float(induced.value)
        if not (want == got or math.isclose(want, got, rel_tol=1e-9, abs_tol=1e-12)):
            problems.append(f"{entry['id']}: MDP {want!r}, induced DTMC {got!r}")
        confirmed += 1
    assert not problems, problems
    assert confirmed >= 40  # 50 of the suite's entries export, as of this writing
