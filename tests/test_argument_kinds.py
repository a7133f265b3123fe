"""An argument of the wrong kind (a file's name where a parsed model belongs, an int where
a mapping does, a dict where a config does) is an ArgumentError that names the argument,
what it was given and the call that gives what is needed: not an AttributeError or a
TypeError from deep inside a stage."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

import veribattery as vb

REPO = Path(__file__).resolve().parents[1]
DICE = REPO / "examples" / "prism" / "dice.pm"
PCTL = REPO / "examples" / "prism" / "dice.pctl"
COIN = REPO / "examples" / "prism" / "coin2.nm"
SIX = "P=? [ F s=7 & d=6 ]"
SMALL = "farm: {cols: 2, rows: 2, base: [0, 0]}\nbattery: {max_recharges: 3}\n"


def _calls() -> dict[str, Callable[[], object]]:
    model = vb.parse_model(DICE)
    flat = vb.flatten_model(model)
    props = vb.parse_properties(SIX).properties
    mdp = vb.check_prism_file(COIN, selectors=['Pmin=? [ F "finished" ]'], constants={"K": 2})
    return {
        "parse_model int": lambda: vb.parse_model(3),  # type: ignore[arg-type]
        "parse_properties bytes": lambda: vb.parse_properties(b"P=? [ F s=7 ]"),  # type: ignore
        "parse_property int": lambda: vb.parse_property(3),  # type: ignore[arg-type]
        "flatten_model path": lambda: vb.flatten_model(DICE),  # type: ignore[arg-type]
        "flatten_model constants int": lambda: vb.flatten_model(model, 3),  # type: ignore
        "build_dtmc model": lambda: vb.build_dtmc(model),  # type: ignore[arg-type]
        "resolve_property model": lambda: vb.resolve_property(props[0], model),  # type: ignore
        "check model": lambda: vb.check(model, props[0]),  # type: ignore[arg-type]
        "check mdp": lambda: vb.check(mdp.mdp, props[0]),  # type: ignore[union-attr,arg-type]
        "check_model path": lambda: vb.check_model(DICE, props),  # type: ignore[arg-type]
        "check_model text": lambda: vb.check_model("dtmc\nmodule m endmodule", props),  # type: ignore
        "check_model flat": lambda: vb.check_model(flat, props),  # type: ignore[arg-type]
        "check_model constants int": lambda: vb.check_model(model, props, constants=3),  # type: ignore
        "check_model options dict": lambda: vb.check_model(
            model, props, options={"keep": "answers"}),  # type: ignore[arg-type]
        "check_model_exact path": lambda: vb.check_model_exact(str(DICE), props),  # type: ignore
        "session options dict": lambda: vb.Session({"keep": "answers"}),  # type: ignore[arg-type]
        "file constants list": lambda: vb.check_prism_file(
            DICE, props_source=PCTL, constants=["x=3"]),  # type: ignore[arg-type]
        "file selector int": lambda: vb.check_prism_file(
            DICE, props_source=PCTL, selectors=[2], constants={"x": 3}),  # type: ignore[list-item]
        "load_config dict": lambda: vb.load_config({"farm": {"cols": 2}}),  # type: ignore
        "load_config int": lambda: vb.load_config(3),  # type: ignore[arg-type]
        "load_config overrides dict": lambda: vb.load_config(
            SMALL, {"farm.cols": 3}),  # type: ignore[arg-type]
        "load_config override int": lambda: vb.load_config(SMALL, [3]),  # type: ignore[list-item]
        "render_model name": lambda: vb.render_model("mission.yaml"),  # type: ignore[arg-type]
        "render_properties dict": lambda: vb.render_properties({}),  # type: ignore[arg-type]
        "mission_files name": lambda: vb.mission_files("mission.yaml"),  # type: ignore[arg-type]
        "check_mission dict": lambda: vb.check_mission({"farm": {}}),  # type: ignore[arg-type]
    }


CASES = [
    ("parse_model int", "source: a Path to read or PRISM text (a str) is needed, not int 3: "
                        "give Path('model.pm'), or the text itself"),
    ("parse_properties bytes", "source: a Path to read or PRISM text (a str) is needed, not "
                               "bytes b'P=? [ F s=7 ]': give Path('model.pm'), or the text"),
    ("parse_property int", "text: one property's text is needed, not int 3: give e.g. "
                           "'P=? [ F \"done\" ]'; a file's properties are "
                           "veribattery.parse_properties(Path('model.props')).properties"),
    ("flatten_model path", "model: a parsed Model is needed, not PosixPath PosixPath("),
    ("flatten_model constants int", "constants: a mapping of constant names to values is "
                                    "needed, not int 3: give a dict such as {'N': 3}"),
    ("build_dtmc model", "model: a flattened model is needed, not Model Model(model_type="),
    ("resolve_property model", "model: a flattened model is needed, not Model Model("),
    ("check model", "dtmc: a built DTMC is needed, not Model Model("),
    ("check mdp", "dtmc: a built DTMC is needed, not MDP MDP(states=272, "),
    ("check_model path", "model: a parsed Model is needed, not PosixPath PosixPath("),
    ("check_model text", "model: a parsed Model is needed, not str 'dtmc\\nmodule m endmodule': "
                         "give veribattery.parse_model(text)"),
    ("check_model flat", "model: a parsed Model is needed, not FlatModel FlatModel("),
    ("check_model constants int", "constants: a mapping of constant names to values is "
                                  "needed, not int 3: give a dict such as {'N': 3}"),
    ("check_model options dict", "options: a CheckOptions is needed, not dict {'keep': "
                                 "'answers'}: give veribattery.CheckOptions(**{'keep': "
                                 "'answers'})"),
    ("check_model_exact path", "model: a parsed Model is needed, not str '"),
    ("session options dict", "options: a CheckOptions is needed, not dict"),
    ("file constants list", "constants: a mapping of constant names to values is needed, "
                            "not list ['x=3']: give "
                            "veribattery.lang.parse_constant_assignments(['x=3'])"),
    ("file selector int", "selectors[0]: a str (a 1-based index, a name or a property's "
                          "text) is needed, not int 2: give '2'"),
    ("load_config dict", "path_or_text: a config file's Path or its YAML text is needed, not "
                         "dict {'farm': {'cols': 2}}: give its YAML text: yaml.safe_dump("),
    ("load_config int", "path_or_text: a config file's Path or its YAML text is needed, not "
                        "int 3: give Path('mission.yaml')"),
    ("load_config overrides dict", "overrides: a list of KEY=VALUE strings is needed, not "
                                   "dict {'farm.cols': 3}: give [f'{key}={value}' for key, "
                                   "value in overrides.items()]"),
    ("load_config override int", "overrides[0]: a KEY=VALUE string is needed, not int 3"),
    ("render_model name", "a loaded mission config is needed, not str 'mission.yaml': give "
                          "veribattery.load_config('mission.yaml')"),
    ("render_properties dict", "a loaded mission config is needed, not dict {}: give "
                               "veribattery.load_config(Path('mission.yaml') or YAML text)"),
    ("mission_files name", "a loaded mission config is needed, not str 'mission.yaml'"),
    # The advice was load_config({'farm': {}}), which failed with an AttributeError.
    ("check_mission dict", "a loaded mission config is needed, not dict {'farm': {}}: give "
                           "veribattery.load_config(Path('mission.yaml') or YAML text)"),
]


@pytest.mark.parametrize(("call", "says"), CASES, ids=[call for call, _ in CASES])
def test_an_argument_of_the_wrong_kind_says_what_is_needed(call: str, says: str) -> None:
    with pytest.raises(vb.VeribatteryError) as info:
        _calls()[call]()
    assert type(info.value).__name__ == "ArgumentError" and isinstance(info.value, ValueError)
    assert str(info.value).startswith(says), str(info.value)


def test_a_path_given_for_a_model_is_named_in_the_call_that_parses_it() -> None:
    props = vb.parse_properties(SIX).properties
    with pytest.raises(vb.VeribatteryError) as info:
        vb.check_model(DICE, props)  # type: ignore[arg-type]
    assert str(info.value).endswith(f"give veribattery.parse_model(Path({str(DICE)!r}))")


def test_a_property_selected_by_its_index_as_a_str_still_works() -> None:
    run = vb.check_prism_file(DICE, props_source=PCTL, selectors=["2"], constants={"x": 3})
    assert [r.value for r in run.results] == [pytest.approx(1 / 6, rel=1e-12)]


def test_no_selectors_as_none_still_checks_the_whole_file() -> None:
    run = vb.check_prism_file(DICE, props_source=PCTL, selectors=None,  # type: ignore[arg-type]
                              constants={"x": 3})
    assert [r.property.text for r in run.results] == [
        "P>0.1 [ F s=7 & d=x ]", SIX, "P=? [ F s=7 & d=x ]", "R=? [ F s=7 ]"]
