"""Resolving properties against a flat model; selecting properties; their errors."""

from __future__ import annotations

import pytest

from tests.lang.helpers import MINI
from veribattery.errors import PrismSemanticError
from veribattery.lang import (
    Binary,
    Eventually,
    FlatModel,
    Ident,
    IntLit,
    LabelRef,
    ProbOp,
    PropertiesFile,
    Property,
    RewardOp,
    TimeBound,
    flatten_model,
    parse_model,
    parse_properties,
    resolve_property,
    select_properties,
)

MODEL = MINI + 'formula twice = 2*x;\nlabel "top" = x=N;\nrewards "steps" true : 1; endrewards\n'


@pytest.fixture
def model() -> FlatModel:
    return flatten_model(parse_model(MODEL, name="t.prism"))


def resolve(model: FlatModel, text: str, constants: dict[str, str] | None = None) -> Property:
    props = parse_properties(text, name="t.props")
    return resolve_property(props.properties[-1], model, props, constants)


def test_constants_formulas_and_labels_are_inlined(model: FlatModel) -> None:
    prop = resolve(
        model,
        'const int k;\nconst int j = k + N;\nlabel "big" = twice > j;\nP=? [ F<=j "big" | "top" ]',
        {"k": "1"},
    )
    assert prop.formula == ProbOp(
        "=?",
        None,
        Eventually(
            Binary(
                "|", Binary(">", Binary("*", IntLit(2), Ident("x")), IntLit(4)), LabelRef("top")
            ),
            TimeBound("<=", IntLit(4)),
        ),
    )
    assert prop.text == 'P=? [ F<=j "big" | "top" ]'


def test_builtin_labels_stay(model: FlatModel) -> None:
    formula = resolve(model, 'P>=1 [ "init" U "deadlock" ]').formula
    assert isinstance(formula, ProbOp)
    assert formula.path == type(formula.path)(LabelRef("init"), LabelRef("deadlock"))  # type: ignore[call-arg]


def test_named_property_is_inlined_where_referenced(model: FlatModel) -> None:
    formula = resolve(model, '"p": P>0.5 [ F x=1 ]\n"p" & x=0').formula
    assert isinstance(formula, Binary) and isinstance(formula.left, ProbOp)


def test_reward_operators(model: FlatModel) -> None:
    formula = resolve(model, 'R{"steps"}=? [ C<=3 ]').formula
    assert isinstance(formula, RewardOp) and formula.reward == "steps"
    assert isinstance(resolve(model, "R=? [ I=2 ]").formula, RewardOp)


def test_unused_undefined_constant_needs_no_value(model: FlatModel) -> None:
    assert resolve(model, "const int unused;\nP=? [ X x=1 ]").formula is not None


def test_undefined_property_constant(model: FlatModel) -> None:
    with pytest.raises(PrismSemanticError) as info:
        resolve(model, "const int k;\nP=? [ F<=k x=1 ]")
    assert (
        str(info.value) == "t.props:1:1: undefined constant k: give a value with --const "
        "k=VALUE, or constants={'k': VALUE} from Python"
    )


def error(model: FlatModel, text: str) -> str:
    with pytest.raises(PrismSemanticError) as info:
        resolve(model, text)
    return str(info.value)


def test_unknown_label(model: FlatModel) -> None:
    assert error(model, 'P=? [ F "nope" ]') == (
        't.props:1:9: unknown label "nope" (known labels: deadlock, init, top)'
    )


def test_unknown_identifier(model: FlatModel) -> None:
    assert error(model, "\nP=? [ F y=1 ]") == "t.props:2:9: unknown identifier 'y'"


def test_unknown_reward_structure(model: FlatModel) -> None:
    assert error(model, 'R{"cost"}=? [ F x=1 ]') == (
        't.props:1:1: unknown reward structure "cost" (the model has "steps")'
    )
    assert "there is no reward structure 2" in error(model, "R{2}=? [ F x=1 ]")


def test_reward_operator_without_reward_structures() -> None:
    bare = flatten_model(parse_model(MINI))
    with pytest.raises(PrismSemanticError, match="needs a reward structure"):
        resolve(bare, "R=? [ C<=2 ]")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("P>1.5 [ F x=1 ]", "t.props:1:3: the probability bound 1.5 is not in [0, 1]"),
        ("P=? [ F<=-1 x=1 ]", "t.props:1:10: a step bound cannot be negative"),
        ('P=? [ F{"steps"}<=-1 x=1 ]', "t.props:1:19: a reward bound cannot be negative"),
        ('P=? [ F{"steps"}<0 x=1 ]', "the reward bound holds for no total (the interval "
                                     "[0,-1] is empty)"),
        ("P=? [ F<=0.5 x=1 ]", "t.props:1:10: type error: a step bound must be an int"),
        ("P=? [ F x+1 ]", "t.props:1:9: type error: the operand of F or G must be a bool, not int"),
        ("P>=true [ F x=1 ]", "type error: the bound of a P or R operator must be a number"),
        # LTL's state formulas are typed too (they reached numpy as ints: a wrong set of
        # states, or numpy's TypeError for a '-' of a bool)
        ("P=? [ G F x ]", "t.props:1:11: type error: an operand of an LTL formula must be a "
                          "bool, not int"),
        ("P=? [ (G x=1) & (F x+1) ]", "t.props:1:20: type error: an operand of an LTL "
                                      "formula must be a bool, not int"),
        ('R{"steps"}=? [ F (X 2) ]', "t.props:1:21: type error: an operand of an LTL formula "
                                     "must be a bool, not int"),
        ("P>=1 [ G F -(x=1) ]", "t.props:1:12: type error: unary '-' needs a number, not bool"),
        # a filter suffix of states that are a path formula (lark's VisitError before)
        ("P=? [ F x=1 {F x=0} ]", "t.props:1:1: unsupported property P=? [ F x=1 {F x=0} ]: "
                                  "temporal operator F (eventually) inside an operator that "
                                  "takes a state formula"),
        ("S=? [ x=1 {x=0 U x=1} ]", "temporal operator U (until) inside an operator"),
        ('R{"steps"}=? [ F x=1 {X x=0}{max} ]', "temporal operator X (next) inside an "),
    ],
)
def test_property_type_and_bound_errors(model: FlatModel, text: str, message: str) -> None:
    assert message in error(model, text)


def test_properties_constant_clashing_with_model(model: FlatModel) -> None:
    assert "'N' is already defined in the model" in error(model, "const int N = 1;\nP=? [ F x=1 ]")


def test_unsupported_property_is_reported_on_resolve(model: FlatModel) -> None:
    message = error(model, "P=? [ F<=2 G x=1 ]")
    assert message.startswith("t.props:1:1: unsupported property P=? [ F<=2 G x=1 ]: a step "
                              "bound on F (eventually) over a path formula")


def props_file() -> PropertiesFile:
    return parse_properties(
        'const int k = 1;\nP=? [ F x=1 ]\nlabel "l" = x=2;\n"b": P=? [ X "l" ]\n'
    )


def test_select_by_index_ignores_definitions() -> None:
    props = props_file()
    assert select_properties(props, "2") == (props.properties[1],)
    assert select_properties(props, "1,b") == props.properties


def test_select_by_name() -> None:
    props = props_file()
    assert select_properties(props, "b")[0].name == "b"
    assert select_properties(props, '"b"')[0].name == "b"


@pytest.mark.parametrize(
    ("selector", "message"),
    [
        ("3", "there is no property 3 in <string> (it has 2 properties)"),
        ("0", "there is no property 0"),
        ("zz", 'there is no property named "zz" in <string> (named properties: "b")'),
    ],
)
def test_select_errors(selector: str, message: str) -> None:
    with pytest.raises(
        PrismSemanticError, match="^" + message.replace("(", r"\(").replace(")", r"\)")
    ):
        select_properties(props_file(), selector)
