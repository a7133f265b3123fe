"""The induced DTMC confirms the optimum: Storm and veribattery, reading the exported
``induced.prism``/``induced.props``, find the MDP's optimal value on it (1e-9), and
Storm finds the same optimum on the MDP itself."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from tests.strategies.models import CASES, Case
from veribattery.pipeline import check_prism_file
from veribattery.pipeline.mdp import MdpCheckRun
from veribattery.strategies import INDUCED_MODEL, INDUCED_PROPERTIES, export_strategy

stormpy = pytest.importorskip("stormpy")

from tests.storm_oracle import close, storm_number  # noqa: E402  (needs stormpy)

RTOL = 1e-9
#: The note the properties file has for W and R (Storm's parser lacks them).
STORM_NOTE = re.compile(r"the value is 1 - (P=\? \[.*\])\)")


def _check_mdp(tmp_path: Path, case: Case) -> MdpCheckRun:
    model = tmp_path / "model.nm"
    model.write_text(case.model, encoding="utf-8")
    run = check_prism_file(model, selectors=(case.prop,), keep="answers")
    assert isinstance(run, MdpCheckRun)
    return run


def _optimum(run: MdpCheckRun, case: Case) -> tuple[float, float]:
    """The MDP's optimum at the initial states, as (lowest, highest)."""
    result = run.results[0]
    if isinstance(result.value, bool):  # P~p: the extreme it reads, solved by hand
        assert isinstance(case.expected, float)
        return case.expected, case.expected
    if result.value_range is not None:
        low, high = result.value_range
        return float(low), float(high)
    return float(result.value), float(result.value)


def _storm_initial_values(model: Path, properties: str, *, exact: bool) -> tuple[float, float]:
    """Storm's value of the first property of *properties*, lowest and highest over
    the initial states (labels and rewards built in full, no property-driven pruning)."""
    program = stormpy.parse_prism_program(str(model))
    formula = stormpy.parse_properties(properties, program)[0]
    # The formula's expressions become labels of the build; a second formula keeps Storm
    # from making the states that decide the first absorbing (tests/storm_oracle.py).
    unused = stormpy.parse_properties('P=? [ F "deadlock" ]', program)
    options = stormpy.BuilderOptions([formula, *unused])
    options.set_build_all_labels()
    options.set_build_all_reward_models()
    built = stormpy.build_model[stormpy.Rational if exact else float](program, options=options)
    values = stormpy.model_checking(built, formula).get_value_vector()
    at_initial = [storm_number(values[s]) for s in built.initial_states]
    return min(at_initial), max(at_initial)


def _agree(got: tuple[float, float], want: tuple[float, float]) -> bool:
    return all(close(g, w, RTOL, 0.0) for g, w in zip(got, want, strict=True))


@pytest.mark.parametrize("case", CASES, ids=str)
def test_storm_confirms_the_optimum_on_the_induced_dtmc(tmp_path: Path, case: Case) -> None:
    run = _check_mdp(tmp_path, case)
    optimum = _optimum(run, case)
    if case.expected is not None:
        expected = case.expected if isinstance(case.expected, tuple) else (case.expected,) * 2
        assert _agree(optimum, expected), (optimum, case.expected)
    folder = tmp_path / "induced"
    export_strategy(run, induced_dir=folder)
    induced = folder / INDUCED_MODEL
    properties = (folder / INDUCED_PROPERTIES).read_text(encoding="utf-8")
    complement = STORM_NOTE.search(properties)
    if complement is None:
        storm = _storm_initial_values(induced, properties, exact=True)
    else:  # W and R: the file's note gives the U whose complement they are
        low, high = _storm_initial_values(induced, complement.group(1), exact=True)
        storm = (1 - high, 1 - low)
    assert _agree(storm, optimum), (storm, optimum, induced.read_text(encoding="utf-8"))


@pytest.mark.parametrize("case", CASES, ids=str)
def test_storm_finds_the_same_optimum_on_the_mdp(tmp_path: Path, case: Case) -> None:
    run = _check_mdp(tmp_path, case)
    if isinstance(run.results[0].value, bool):
        pytest.skip("a bounded P~p has a truth value; its optimum is checked above")
    if case.storm_prop is None:
        pytest.skip("Storm's parser reads no W, R or R{k}; the induced DTMC checks these")
    try:
        storm = _storm_initial_values(tmp_path / "model.nm", case.storm_prop, exact=True)
        rtol = RTOL
    except RuntimeError:  # Storm's exact MDP engine lacks some objectives
        storm, rtol = _storm_initial_values(tmp_path / "model.nm", case.storm_prop,
                                            exact=False), 1e-6
    got = _optimum(run, case)
    assert all(close(g, w, rtol, 1e-12) for g, w in zip(got, storm, strict=True)), (got, storm)


@pytest.mark.parametrize("case", CASES, ids=str)
def test_veribattery_confirms_the_optimum_on_the_induced_dtmc(tmp_path: Path,
                                                              case: Case) -> None:
    run = _check_mdp(tmp_path, case)
    folder = tmp_path / "induced"
    export_strategy(run, induced_dir=folder)
    dtmc_run = check_prism_file(folder / INDUCED_MODEL, props_source=folder / INDUCED_PROPERTIES,
                                keep="answers")
    assert not isinstance(dtmc_run, MdpCheckRun)
    result = dtmc_run.results[0]
    got = (result.value_range if result.value_range is not None
           else (result.value, result.value))
    assert _agree((float(got[0]), float(got[1])), _optimum(run, case))


def test_the_induced_model_keeps_only_states_the_strategy_reaches(tmp_path: Path) -> None:
    """Pmax of the robot goes east: the broken state (reached only by risky) is gone."""
    run = _check_mdp(tmp_path, CASES[0])
    export_strategy(run, induced_dir=tmp_path / "out")
    text = (tmp_path / "out" / INDUCED_MODEL).read_text(encoding="utf-8")
    commands = [line.strip() for line in text.splitlines() if "->" in line]
    assert commands == [
        "[east] x=0 & !done -> 0.2:true + 0.8:(x'=1);",
        "[east] x=1 & !done -> 0.2:true + 0.8:(x'=2);",
        "[stay] x=3 & !done -> true;",
        "[east] x=2 & !done -> 0.8:(x'=3) + 0.2:true;",
    ]
    assert "x : [0..3] init 0;" in text and "done : bool init false;" in text
    assert not math.isnan(run.results[0].value)
