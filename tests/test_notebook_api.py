"""The library as a notebook user meets it: what its objects show, and what its errors say."""

from __future__ import annotations

from pathlib import Path

import pytest

import veribattery as vb

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "prism"
DICE = EXAMPLES / "dice.pm"
COIN = EXAMPLES / "coin2.nm"
SIX = 'P=? [ F s=7 & d=6 ]'


@pytest.fixture(scope="module")
def mdp_run() -> object:
    return vb.check_prism_file(COIN, selectors=['Pmin=? [ F "finished" ]'], constants={"K": 2})


def test_a_dtmc_run_shows_sizes_and_answers_not_arrays() -> None:
    run = vb.check_model(vb.parse_model(DICE), vb.parse_properties(SIX).properties)
    shown = repr(run)
    assert shown.startswith(
        "ModelCheckRun(dtmc=DTMC(states=13, transitions=20, initial=1, variables=('s', 'd'), "
        "labels=('init', 'deadlock'), rewards=('coin_flips',), deadlocks=0), "
        "results=(CheckResult(property=Property(name=None, text='P=? [ F s=7 & d=6 ]'), "
        "value=0.16666666666666666, ")
    assert "array(" not in shown and "Span(" not in shown and len(shown) < 700


def test_an_exact_result_shows_its_fraction_not_every_state() -> None:
    run = vb.check_model_exact(vb.parse_model(DICE), vb.parse_properties(SIX).properties)
    shown = repr(run.results[0])
    assert shown.startswith("ExactCheckResult(property=Property(name=None, text='P=? [ F s=7")
    assert shown.endswith("exact=Fraction(1, 6))") and "mpq" not in shown


def test_an_mdp_run_and_its_strategy_show_sizes(mdp_run: vb.ModelCheckRun) -> None:
    shown = repr(mdp_run)
    assert shown.startswith("MdpCheckRun(mdp=MDP(states=272, choices=400, transitions=492, "
                            "initial=1, variables=('counter', 'pc1', 'coin1', 'pc2', 'coin2')")
    assert "array(" not in shown and "FlatModel" not in shown and len(shown) < 800
    assert repr(mdp_run.strategy(0)) == "Strategy(states=272)"  # type: ignore[attr-defined]


def test_a_mission_report_shows_its_answers_not_its_config() -> None:
    report = vb.check_mission(vb.load_config(
        "farm: {cols: 2, rows: 2, base: [0, 0]}\nbattery: {max_recharges: 5}\n"))
    shown = repr(report)
    assert shown.startswith("MissionReport(run=ModelCheckRun(dtmc=DTMC(states=")
    assert "Property(name='p_success', text='P=? [ F \"success\" ]'), value=" in shown
    assert "MissionConfig" not in shown and "array(" not in shown


@pytest.mark.parametrize("call", ["check_model", "check_model_exact", "build_dtmc"])
def test_a_dtmc_function_given_an_mdp_names_the_function_that_checks_one(call: str) -> None:
    model = vb.parse_model(COIN)
    props = vb.parse_properties('Pmin=? [ F "finished" ]').properties
    run = {"check_model": lambda: vb.check_model(model, props, constants={"K": 2}),
           "check_model_exact": lambda: vb.check_model_exact(model, props, constants={"K": 2}),
           "build_dtmc": lambda: vb.build_dtmc(vb.flatten_model(model, {"K": 2}))}[call]
    with pytest.raises(vb.PrismSemanticError) as info:
        run()
    assert str(info.value) == (
        "this is an MDP, but this builds a DTMC and needs a 'dtmc' model: check an MDP's "
        "properties with veribattery.check_prism_file (from Python) or 'veribattery prism' "
        "without --explain or --simulate")
