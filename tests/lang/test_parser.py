"""Parsing: each construct of the subset, and syntax errors with file:line:col."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.lang.helpers import MINI
from veribattery.errors import PrismSemanticError, PrismSyntaxError, VeribatteryError
from veribattery.lang import (
    Binary,
    BoolLit,
    Call,
    Cumulative,
    DoubleLit,
    Eventually,
    Globally,
    Ident,
    Instantaneous,
    IntLit,
    Ite,
    LabelRef,
    Module,
    Next,
    ProbOp,
    Reach,
    RenamedModule,
    RewardOp,
    TimeBound,
    Unary,
    Until,
    parse_model,
    parse_properties,
    parse_property,
)


def expr(text: str) -> object:
    """The state formula of ``P=? [ F text ]``."""
    formula = parse_property(f"P=? [ F {text} ]").formula
    assert isinstance(formula, ProbOp) and isinstance(formula.path, Eventually)
    return formula.path.operand


def test_model_constructs() -> None:
    model = parse_model(
        """probabilistic
        const int N = 2; const double p; const bool b = true; const K;
        formula f = x + 1;
        global g : [0..N] init 1;
        module m
          x : [0..N] init 0;
          y : bool init false;
          [go] x<N & !y -> p:(x'=x+1)&(y'=true) + 1-p:true;
          [] x=N -> (x'=0);
        endmodule
        module m2 = m [x=x2, y=y2, go=stop] endmodule
        label "done" = x=N;
        rewards "r" [go] true : 1; x>0 : x; endrewards
        rewards y : 2; endrewards
        init x=0 endinit
        """
    )
    assert [c.type for c in model.constants] == ["int", "double", "bool", "int"]
    assert model.constants[1].value is None
    assert model.formulas[0].name == "f"
    assert model.globals[0].name == "g"
    module = model.modules[0]
    assert isinstance(module, Module)
    assert [v.type for v in module.variables] == ["int", "bool"]
    first, second = module.commands
    assert first.action == "go" and second.action is None
    assert len(first.updates) == 2 and first.updates[1].assignments == ()
    assert second.updates[0].probability == IntLit(1)
    renamed = model.modules[1]
    assert isinstance(renamed, RenamedModule)
    assert renamed.renames == (("x", "x2"), ("y", "y2"), ("go", "stop"))
    assert model.labels[0].name == "done"
    assert model.rewards[0].name == "r" and model.rewards[1].name is None
    assert [i.is_transition for i in model.rewards[0].items] == [True, False]
    assert model.init is not None


def test_spans_point_into_the_source() -> None:
    model = parse_model(MINI, name="mini.prism")
    module = model.modules[0]
    assert isinstance(module, Module)
    command = module.commands[0]
    assert str(command.span) == "mini.prism:5:3"
    assert str(command.guard.span) == "mini.prism:5:7"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("a | b & c", Binary("|", Ident("a"), Binary("&", Ident("b"), Ident("c")))),
        ("!a = b", Unary("!", Binary("=", Ident("a"), Ident("b")))),
        ("a => b <=> c", Binary("=>", Ident("a"), Binary("<=>", Ident("b"), Ident("c")))),
        ("a = b < c", Binary("=", Ident("a"), Binary("<", Ident("b"), Ident("c")))),
        ("1 + 2 * 3", Binary("+", IntLit(1), Binary("*", IntLit(2), IntLit(3)))),
        ("1 - 2 - 3", Binary("-", Binary("-", IntLit(1), IntLit(2)), IntLit(3))),
        ("-x * 2", Binary("*", Unary("-", Ident("x")), IntLit(2))),
        ("c ? 1 : 2.5", Ite(Ident("c"), IntLit(1), DoubleLit(2.5, "2.5"))),
        ("a ? b : c ? d : e", Ite(Ident("a"), Ident("b"), Ite(Ident("c"), Ident("d"), Ident("e")))),
        ("min(x, 1, 2)", Call("min", (Ident("x"), IntLit(1), IntLit(2)))),
        ("func(mod, x, 2)", Call("mod", (Ident("x"), IntLit(2)))),
        ('"done" & true', Binary("&", LabelRef("done"), BoolLit(True))),
        (
            "s=7 & d=x",
            Binary("&", Binary("=", Ident("s"), IntLit(7)), Binary("=", Ident("d"), Ident("x"))),
        ),
    ],
)
def test_operator_precedence(text: str, expected: object) -> None:
    assert expr(text) == expected


def test_double_literal_keeps_its_text() -> None:
    assert expr("x = 1.50e-3") == Binary("=", Ident("x"), DoubleLit(1.5e-3, "1.50e-3"))


@pytest.mark.parametrize(
    ("text", "path"),
    [
        ("P=? [ X a ]", Next(Ident("a"))),
        ("P=? [ F a ]", Eventually(Ident("a"))),
        ("P=? [ G a ]", Globally(Ident("a"))),
        ("P=? [ a U b ]", Until(Ident("a"), Ident("b"))),
        ("P=? [ F<=5 a ]", Eventually(Ident("a"), TimeBound("<=", IntLit(5)))),
        ("P=? [ F>=k a ]", Eventually(Ident("a"), TimeBound(">=", Ident("k")))),
        ("P=? [ G<4 a ]", Globally(Ident("a"), TimeBound("<", IntLit(4)))),
        ("P=? [ a U>2 b ]", Until(Ident("a"), Ident("b"), TimeBound(">", IntLit(2)))),
    ],
)
def test_probability_paths(text: str, path: object) -> None:
    formula = parse_property(text).formula
    assert formula == ProbOp("=?", None, path)  # type: ignore[arg-type]


def test_probability_bound_and_nesting() -> None:
    formula = parse_property('P>=0.5 [ F "a" ] & !P<1/6 [ X b ]').formula
    assert isinstance(formula, Binary) and formula.op == "&"
    left = formula.left
    assert isinstance(left, ProbOp) and left.op == ">=" and left.bound == DoubleLit(0.5, "0.5")


@pytest.mark.parametrize(
    ("text", "reward", "path"),
    [
        ('R{"time"}=? [ F a ]', "time", Reach(Ident("a"))),
        ("R=? [ C<=10 ]", None, Cumulative(IntLit(10))),
        ("R{2}=? [ I=3 ]", 1, Instantaneous(IntLit(3))),
    ],
)
def test_reward_operators(text: str, reward: object, path: object) -> None:
    assert parse_property(text).formula == RewardOp(reward, "=?", None, path)  # type: ignore[arg-type]


def test_properties_file_with_optional_semicolons() -> None:
    props = parse_properties(
        'const int k = 2;\nlabel "l" = x>1;\n"named": P=? [ F "l" ];\n'
        "P>0.1 [ F<=k x=1 ]\n// comment\nR=? [ C<=k ]\n"
    )
    assert [c.name for c in props.constants] == ["k"]
    assert [lab.name for lab in props.labels] == ["l"]
    assert [p.name for p in props.properties] == ["named", None, None]
    assert [p.text for p in props.properties] == [
        'P=? [ F "l" ]',
        "P>0.1 [ F<=k x=1 ]",
        "R=? [ C<=k ]",
    ]


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("P=? [ F<=3 G x=1 ]", "a step bound on F (eventually) over a path formula"),
        ("P=? [ (G<=2 x=1) & (F x=0) ]", "a step bound on G (globally) inside an LTL"),
        ("P=? [ (X x=1) + 1 ]", "temporal operator X (next) inside an operator that takes"),
        ("filter(max, P=? [ X X x=1 ], F x=1)", "temporal operator F (eventually) inside"),
        ("P=? [ (F G x=1) || F x=0 ]", "takes one temporal operator over state formulas"),
        ("R=? [ F<=3 x=1 ]", "co-safe"),
        ("F x=1", "P or R operator"),
    ],
)
def test_unsupported_properties_parse_with_a_reason(text: str, reason: str) -> None:
    prop = parse_property(text)
    assert prop.unsupported is not None and reason in prop.unsupported


def test_syntax_error_names_token_and_position(tmp_path: Path) -> None:
    path = tmp_path / "model.prism"
    path.write_text("dtmc\nmodule m\n  x : [0..1];\n  [] x=0 -> (x'=1) -> ;\nendmodule\n")
    with pytest.raises(PrismSyntaxError) as info:
        parse_model(path)
    assert str(info.value).startswith(f"{path}:4:20: unexpected token '->' (expected ")
    assert "';'" in info.value.message
    assert info.value.span is not None and (info.value.span.line, info.value.span.col) == (4, 20)


def test_syntax_error_expected_expression() -> None:
    with pytest.raises(
        PrismSyntaxError, match=r"<string>:1:32: unexpected token ';' \(expected an expression"
    ):
        parse_model("dtmc module m x : [0..1]; [] x=;")


@pytest.mark.parametrize("update", ["[0.1,0.2]:(x'=1) + [0.8,0.9]:(x'=0)",
                                    "0.5:(x'=1) + [0.4,0.5]:(x'=0)"])
def test_an_interval_probability_names_interval_models(update: str) -> None:
    # PRISM reads "dtmc" with interval probabilities as an IDTMC (prism-tests/.../idtmcs).
    text = f"dtmc\nmodule m\n  x : [0..1];\n  [] x=0 -> {update};\nendmodule\n"
    col = text.splitlines()[3].index("[", 4) + 1
    with pytest.raises(PrismSyntaxError,
                       match=rf"^m:4:{col}: an interval probability .* interval model"):
        parse_model(text, name="m")


@pytest.mark.parametrize(("text", "name"), [
    ("fiter(forall, x<=1)", "fiter"),       # PRISM's own leader.pctl has this typo
    ("P=? [ F x=mx(1, 0) ]", "mx")])
def test_a_call_of_an_unknown_function_is_named(text: str, name: str) -> None:
    with pytest.raises(PrismSyntaxError, match=rf"unknown function '{name}' \(PRISM's functions"):
        parse_properties(text, name="p")
    # One property alone (--property): a name then a parenthesis is no two properties.
    with pytest.raises(PrismSyntaxError, match="unknown function 'flor'"):
        parse_property("flor(x/2)")


@pytest.mark.parametrize("text", ["P=? [ F (x=1 ]", "P=? [ F x=1 ] + (2,3)"])
def test_a_keyword_or_an_operator_before_a_parenthesis_is_no_call(text: str) -> None:
    with pytest.raises(PrismSyntaxError, match="unexpected token"):
        parse_properties(text, name="p")


def test_unexpected_character_and_end_of_input() -> None:
    with pytest.raises(PrismSyntaxError, match=r"^m:2:3: unexpected character '#'"):
        parse_model("dtmc\n  # oops", name="m")
    with pytest.raises(PrismSyntaxError, match=r"unexpected end of input"):
        parse_model("dtmc module m x : [0..1];")


def test_missing_file_is_an_error_not_a_traceback(tmp_path: Path) -> None:
    with pytest.raises(PrismSyntaxError, match="file not found"):
        parse_model(tmp_path / "nope.prism")


def test_a_str_is_text_never_a_path(tmp_path: Path) -> None:
    path = tmp_path / "m.prism"
    path.write_text(MINI)
    with pytest.raises(PrismSyntaxError):
        parse_model(str(path))


@pytest.mark.parametrize("kind", ["ctmc", "stochastic", "pta"])
def test_only_dtmc_and_mdp_models(kind: str) -> None:
    with pytest.raises(
        PrismSemanticError,
        match=f"^<string>:1:1: only DTMC and MDP models are supported, not '{kind}'",
    ):
        parse_model(MINI.replace("dtmc", kind))


@pytest.mark.parametrize(("kind", "parsed"), [
    ("dtmc", "dtmc"), ("probabilistic", "dtmc"), ("mdp", "mdp"), ("nondeterministic", "mdp"),
    ("", "mdp"),  # PRISM: a model without a type is an MDP
])
def test_model_types(kind: str, parsed: str) -> None:
    assert parse_model(MINI.replace("dtmc", kind)).model_type == parsed


def test_the_dtmc_builder_refuses_an_mdp() -> None:
    from veribattery.explore import build_dtmc
    from veribattery.lang import flatten_model

    with pytest.raises(PrismSemanticError, match="this is an MDP"):
        build_dtmc(flatten_model(parse_model(MINI.replace("dtmc", "mdp"))))


def test_temporal_operator_in_a_model_is_a_syntax_error() -> None:
    with pytest.raises(PrismSyntaxError, match="5:7"):
        parse_model(MINI.replace("x<N ->", "F x<N ->"))


def test_true_update_may_stand_anywhere_in_a_sum() -> None:
    model = parse_model(
        "dtmc\nmodule m\n  w : [0..1] init 0;\n"
        "  [] w=0 -> 0.5:true + 0.5:(w'=1);\n  [] w=1 -> 0.25:(w'=0) + 0.75:true;\n"
        "  [] w=1 -> true;\nendmodule\n"
    )
    first, second, lone = model.modules[0].commands  # type: ignore[union-attr]
    assert [len(u.assignments) for u in first.updates] == [0, 1]
    assert [len(u.assignments) for u in second.updates] == [1, 0]
    assert len(lone.updates) == 1 and lone.updates[0].assignments == ()


def test_a_model_file_that_is_not_utf8_is_located(tmp_path) -> None:
    from veribattery.errors import PrismSyntaxError
    from veribattery.lang import parse_model

    path = tmp_path / "bad.pm"
    path.write_bytes(b"dtmc\nmodule m\n  s : [0..1] init 0; // caf\xe9\nendmodule\n")
    with pytest.raises(PrismSyntaxError) as raised:
        parse_model(path)
    assert str(raised.value) == f"{path}:3:28: not UTF-8 text (byte 0xe9); save the file as UTF-8"


def test_a_model_file_may_start_with_a_byte_order_mark(tmp_path) -> None:
    from veribattery.lang import parse_model

    path = tmp_path / "bom.pm"
    path.write_bytes(b"\xef\xbb\xbfdtmc\nmodule m\n  s : [0..1] init 0;\nendmodule\n")
    assert parse_model(path).modules[0].name == "m"


@pytest.mark.parametrize(("model_type", "body"), [
    ("pomdp", "observables x endobservables\n"),  # (PRISM's POMDPs: an observables block)
    ("popta", "module m\n  c : clock;\nendmodule\n"),
    ("csg", "player p1 m endplayer\n"), ("tsg", ""), ("lts", ""), ("ctmc", ""), ("pta", ""),
])
def test_other_model_types_are_refused_by_name(model_type: str, body: str) -> None:
    # They were "unexpected token 'pomdp'" (or a later token, for pta's clocks); the
    # model-type line is named, as for ctmc.
    text = f"// a {model_type}\n\n  {model_type}\n{body}module n\n  y : [0..1];\nendmodule\n"
    with pytest.raises(VeribatteryError, match=rf"^m:3:3: only DTMC and MDP models are "
                                               rf"supported, not '{model_type}'"):
        parse_model(text, name="m")


@pytest.mark.parametrize(("text", "says"), [
    ("dtmc\nmodule m\n  x : int init 0;\nendmodule\n",
     r"^m:3:7: an unbounded int variable is not supported .*: give it a range"),
    ("dtmc\nmodule m\n  x : [0..1];\nendmodule\nsystem m endsystem\n",
     r"^m:5:1: a system \.\.\. endsystem block .* is not supported; without it every module"),
])
def test_unsupported_declarations_are_named(text: str, says: str) -> None:
    # (Storm's test models: "unexpected token 'int' (expected 'bool' or '[')", "... 'system'")
    with pytest.raises(PrismSyntaxError, match=says):
        parse_model(text, name="m")


def test_a_temporal_operator_read_as_a_name_is_named_with_the_parentheses_it_needs() -> None:
    # (Storm's die tests: P=? [ F (s=6) & X "done" ] said only "unexpected token")
    with pytest.raises(PrismSyntaxError, match=r"unexpected token '\"done\"' .*; 'X' before it "
                                               r"reads as a temporal operator .* \(X \.\.\.\)"):
        parse_property('P=? [ F (s=6) & X "done" ]')
    with pytest.raises(PrismSyntaxError) as plain:
        parse_property("P=? [ F s=; ]")
    assert "temporal" not in str(plain.value)


def test_a_properties_file_is_never_taken_for_a_model_type() -> None:
    # (a constant named like a model type, first in a properties file)
    with pytest.raises(PrismSyntaxError) as raised:
        parse_properties("lts + = 1;\n", name="p")
    assert "model" not in str(raised.value)


@pytest.mark.parametrize(("text", "says"), [
    ('P=? [ F{"a"}>=2,{"a"}<3 "done" ]', r"^<property>:1:16: several reward bounds on one F"),
    ('R{"a"}=? [ C{"b"}<=3 ]', r"^<property>:1:18: a reward-bounded C \(Storm's"),
    ("P=? [ F s=1, ]", r"^<property>:1:12: unexpected token ','"),  # (no reward bound here)
])
def test_storm_only_reward_bounds_are_named(text: str, says: str) -> None:
    # (Storm's leader and crowds tests: "unexpected token ','" and "... '<='")
    with pytest.raises(PrismSyntaxError, match=says):
        parse_property(text)
