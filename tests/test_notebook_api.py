"""The library as a notebook user meets it: what its objects show, and what its errors say."""

from __future__ import annotations

from pathlib import Path

import pytest

import veribattery as vb
from veribattery.sweep import Axis

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "examples" / "prism"
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


def _dice_calls() -> dict[str, object]:
    model = vb.parse_model(DICE)
    props = vb.parse_properties(SIX)
    dtmc = vb.build_dtmc(vb.flatten_model(model))
    return {
        "check text": lambda: vb.check(dtmc, SIX),
        "check keep": lambda: vb.check(dtmc, props.properties[0], keep="all"),  # type: ignore
        "check_model text": lambda: vb.check_model(model, SIX),  # type: ignore[arg-type]
        "check_model one": lambda: vb.check_model(model, props.properties[0]),  # type: ignore
        "check_model file": lambda: vb.check_model(model, props),  # type: ignore[arg-type]
        "check_model_exact text": lambda: vb.check_model_exact(model, SIX),  # type: ignore
        "options keep": lambda: vb.CheckOptions(keep="all"),  # type: ignore[arg-type]
        "session lump": lambda: vb.Session(lump=True),
        "session rewards": lambda: vb.Session(rewards="some"),  # type: ignore[arg-type]
        "file keep": lambda: vb.check_prism_file(DICE, selectors=[SIX], keep="all"),  # type: ignore
        "mdp rewards": lambda: vb.check_prism_file(  # an MDP's check read only "named"
            COIN, selectors=['Pmin=? [ F "finished" ]'], constants={"K": 2},
            rewards="some"),  # type: ignore[arg-type]
    }


@pytest.mark.parametrize(("call", "says"), [
    ("check text", "check takes a parsed property, not the text 'P=? [ F s=7 & d=6 ]': give "
                   "veribattery.parse_property('P=? [ F s=7 & d=6 ]')"),
    ("check keep", "keep must be one of ('states', 'answers'), got 'all'"),
    ("check_model text", "properties: parsed properties are needed, not text: give "
                         "veribattery.parse_properties('P=? [ F s=7 & d=6 ]').properties"),
    ("check_model one", "properties: a sequence of properties is needed, not one Property: "
                        "give (prop,)"),
    ("check_model file", "properties: a sequence of properties is needed, not a "
                         "PropertiesFile: give props.properties, and props_file=props for "
                         "its constants and labels"),
    ("check_model_exact text", "properties: parsed properties are needed, not text"),
    ("options keep", "keep must be one of ('states', 'answers'), got 'all'"),
    ("session lump", 'lumping keeps answers only: give CheckOptions(keep="answers")'),
    ("session rewards", "rewards must be one of ('all', 'named'), got 'some'"),
    ("file keep", "keep must be one of ('states', 'answers'), got 'all'"),
    ("mdp rewards", "rewards must be one of ('all', 'named'), got 'some'"),
])
def test_a_wrong_argument_is_a_veribattery_error_that_says_what_is_right(
        call: str, says: str) -> None:
    with pytest.raises(vb.VeribatteryError) as info:
        _dice_calls()[call]()  # type: ignore[operator]
    assert str(info.value).startswith(says)
    assert type(info.value).__name__ == "ArgumentError" and isinstance(info.value, ValueError)


@pytest.mark.parametrize("call", ["check_model", "check_model_exact", "check_prism_file"])
def test_a_constant_the_model_does_not_declare_is_refused(call: str) -> None:
    model, props = vb.parse_model(DICE), vb.parse_properties(SIX).properties
    run = {"check_model": lambda: vb.check_model(model, props, constants={"X": 3}),
           "check_model_exact": lambda: vb.check_model_exact(model, props, constants={"X": 3}),
           "check_prism_file": lambda: vb.check_prism_file(DICE, selectors=[SIX],
                                                           constants={"X": 3})}[call]
    with pytest.raises(vb.PrismSemanticError) as info:
        run()
    assert str(info.value) == (
        "constant X: declared neither in the model nor in its properties, but given a value "
        "(by --const, or constants= from Python); the undefined constants are: none")


def test_a_missing_constant_says_how_to_give_it_from_python() -> None:
    with pytest.raises(vb.PrismSemanticError) as info:
        vb.check_prism_file(COIN, selectors=['Pmin=? [ F "finished" ]'])
    assert str(info.value).endswith(
        "undefined constant K: give a value with --const K=VALUE, or constants={'K': VALUE} "
        "from Python")


def test_one_selector_as_a_str_is_one_selector_not_one_per_character() -> None:
    pctl = EXAMPLES / "dice.pctl"
    run = vb.check_prism_file(DICE, props_source=pctl, selectors="2", constants={"x": 3})
    assert [(r.property.text, r.value) for r in run.results] == [(SIX, pytest.approx(1 / 6))]
    with pytest.raises(vb.PrismSemanticError, match="there is no property 12 in "):
        vb.check_prism_file(DICE, props_source=pctl, selectors="12", constants={"x": 3})


def test_no_property_says_how_to_give_one_from_python() -> None:
    with pytest.raises(vb.PrismSemanticError) as info:
        vb.check_prism_file(DICE)
    assert str(info.value) == ("no property given: use --props FILE or --property TEXT "
                               "(props_source= or selectors= from Python)")


def test_a_strategy_past_the_results_names_how_many_there_are(mdp_run: object) -> None:
    with pytest.raises(vb.VeribatteryError) as info:
        mdp_run.strategy(1)  # type: ignore[attr-defined]
    assert str(info.value) == ("strategy(1): there is no result 1; this run has 1 "
                               "(0-based: 0 to 0)")
    assert repr(mdp_run.strategy(-1)) == "Strategy(states=272)"  # type: ignore[attr-defined]


def test_a_config_file_name_given_to_check_mission_says_to_load_it() -> None:
    for check in (vb.check_mission, vb.MissionSession().check):
        with pytest.raises(vb.VeribatteryError) as info:
            check("configs/paper/case1.yaml")  # type: ignore[arg-type]
        assert str(info.value) == (
            "a loaded mission config is needed, not str 'configs/paper/case1.yaml': give "
            "veribattery.load_config('configs/paper/case1.yaml')")


@pytest.mark.parametrize(("axes", "says"), [
    (["strategy.safe_t=0.25,0.3"], "axes[0] is 'strategy.safe_t=0.25,0.3', not an Axis: give "
                                   "veribattery.sweep.parse_axis('strategy.safe_t=0.25,0.3')"),
    ("strategy.safe_t=0.25", "axes: a list of axes is needed, not 'strategy.safe_t=0.25': give "
                             "[axis], each from veribattery.sweep.parse_axis('KEY=SPEC')"),
    ([("strategy.safe_t", 0.25)], "axes[0] is ('strategy.safe_t', 0.25), not an Axis: give "
                                  "veribattery.sweep.parse_axis('KEY=SPEC')"),
])
def test_a_sweep_axis_as_text_says_how_to_make_one(axes: object, says: str) -> None:
    with pytest.raises(vb.VeribatteryError) as info:
        vb.run_sweep("", axes)  # type: ignore[arg-type]
    assert str(info.value) == says


def test_one_override_as_a_str_is_one_override() -> None:
    cfg = vb.load_config(REPO / "configs/paper/case1.yaml", "strategy.safe_t=0.3")  # type: ignore
    assert str(cfg.strategy.safe_t) == "3/10"


@pytest.mark.parametrize("parse", [vb.parse_model, vb.parse_properties])
def test_a_file_name_as_a_str_says_to_give_a_path(parse: object) -> None:
    name = str(DICE)
    with pytest.raises(vb.PrismSyntaxError) as info:
        parse(name)  # type: ignore[operator]
    assert str(info.value) == (f"{name!r} was parsed as PRISM text, since a str is the text "
                               f"itself: give Path({name!r}) to read the file")


def test_text_that_does_not_parse_still_says_where() -> None:
    with pytest.raises(vb.PrismSyntaxError, match=r"^<string>:1:34: unexpected end of input"):
        vb.parse_model("dtmc module m x : bool; [] x -> x")


def test_a_sweep_on_no_workers_is_refused_before_any_work() -> None:
    """A pool of none failed on the second point with concurrent.futures' ValueError."""
    config = "farm: {cols: 2, rows: 2, base: [0, 0]}\nbattery: {max_recharges: 3}\n"
    axes = [Axis("farm.cols", (2, 3))]
    with pytest.raises(vb.VeribatteryError) as info:
        vb.run_sweep(config, axes, jobs=0)
    assert str(info.value) == "jobs must be at least 1 (1: in this process), got 0"


def test_a_parsed_model_shows_its_declarations_not_its_expressions() -> None:
    """These showed every expression with a span on each node: 10 kB for the die."""
    model = vb.parse_model(DICE)
    source = str(DICE)
    assert repr(model) == (
        f"Model(model_type='dtmc', source={source!r}, constants=(), globals=(), "
        "modules=('die',), commands=8, labels=(), rewards=('coin_flips',))")
    assert repr(vb.flatten_model(vb.parse_model(COIN), {"K": 2})).startswith(
        "FlatModel(model_type='mdp', source=" + repr(str(COIN)) + ", constants={'N': 2, "
        "'K': 2, 'range': 12, 'counter_init': 6, 'left': 2, 'right': 10}, variables=("
        "'counter', 'pc1', 'coin1', 'pc2', 'coin2'), modules=('process1', 'process2'), "
        "commands=14, ")


def test_properties_show_their_names_and_texts() -> None:
    props = vb.parse_properties(EXAMPLES / "dice.pctl")
    assert repr(props) == (
        f"PropertiesFile(source={str(EXAMPLES / 'dice.pctl')!r}, constants=('x',), labels=(), "
        "properties=(Property(name=None, text='P>0.1 [ F s=7 & d=x ]'), Property(name=None, "
        "text='P=? [ F s=7 & d=6 ]'), Property(name=None, text='P=? [ F s=7 & d=x ]'), "
        "Property(name=None, text='R=? [ F s=7 ]')))")
    assert repr(vb.parse_property('"six": ' + SIX)) == f"Property(name='six', text={SIX!r})"


def test_sessions_and_mission_files_show_what_they_hold() -> None:
    """Sessions showed <... object at 0x...>; the files, 12,000 characters of model."""
    assert repr(vb.Session(vb.CheckOptions(keep="answers"), lump=True)) == (
        "Session(options=CheckOptions(keep='answers', undefined_as_nan=False, "
        "report_undecided=False), reuse=True, lump=True, rewards='all')")
    assert repr(vb.MissionSession.for_sweep()) == (
        "MissionSession(keep='answers', reuse=True, lump=False, rewards='named')")
    files = vb.mission_files(vb.load_config("farm: {cols: 2, rows: 2, base: [0, 0]}\n"))
    assert repr(files) == (
        f"MissionFiles(model=<{len(files.model):,} characters>, properties=<"
        f"{len(files.properties):,} characters>, storm_only=<{len(files.storm_only):,} "
        f"characters>, config=<{len(files.config):,} characters>)")
    assert len(files.model) > 5000


def test_a_column_of_no_variable_names_the_variables() -> None:
    dtmc = vb.build_dtmc(vb.flatten_model(vb.parse_model(DICE)))
    assert dtmc.column("d").tolist()[:3] == [0, 0, 0]
    with pytest.raises(vb.VeribatteryError) as info:
        dtmc.column("z")
    assert str(info.value) == "no variable 'z': the variables are ('s', 'd')"
    assert isinstance(info.value, ValueError)
