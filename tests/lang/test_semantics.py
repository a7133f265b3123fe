"""Semantic analysis of models: constants, formulas, renaming, flat model, errors."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tests.lang.helpers import MINI, PEER
from veribattery.errors import PrismSemanticError
from veribattery.lang import (
    Binary,
    DoubleLit,
    FlatModel,
    Ident,
    IntLit,
    flatten_model,
    parse_constant_assignments,
    parse_model,
    undefined_constants,
)
from veribattery.lang.evaluate import evaluate
from veribattery.lang.ops import modulo


def flat(text: str, constants: dict[str, object] | None = None) -> FlatModel:
    return flatten_model(parse_model(text, name="t.prism"), constants)  # type: ignore[arg-type]


def const_value(expression: str, kind: str = "double") -> object:
    model = flat(f"dtmc\nconst {kind} c = {expression};\nmodule m x : bool; endmodule\n")
    return dict(model.constants)["c"]


@pytest.mark.parametrize(
    ("expression", "kind", "value"),
    [
        ("22/7", "double", 22 / 7),
        ("7/2", "double", 3.5),
        ("floor(7/2)", "int", 3),
        ("ceil(7/2)", "int", 4),
        ("pow(2, 10)", "int", 1024),
        ("pow(2, 62)", "int", 2**62),
        ("pow(9.0, 0.5)", "double", 3.0),
        ("mod(7, 3)", "int", 1),
        ("mod(-7, 3)", "int", 2),
        ("min(3, 1, 2)", "int", 1),
        ("max(1, 2.5)", "double", 2.5),
        ("log(8, 2)", "double", 3.0),
        ("2 * 3 + 4", "int", 10),
        ("10 - 2 - 3", "int", 5),
        ("true ? 1 : 2", "int", 1),
        ("1 < 2 & !(2 = 3)", "bool", True),
        ("false => false", "bool", True),
        ("1", "double", 1.0),
    ],
)
def test_constant_evaluation(expression: str, kind: str, value: object) -> None:
    result = const_value(expression, kind)
    assert result == value
    assert type(result) is type(value)


def test_prism_mod_sign_convention() -> None:
    assert [modulo(i, 3) for i in (-4, -3, -1, 0, 1, 4)] == [2, 0, 2, 0, 1, 1]


def test_division_by_zero_is_infinite_like_java() -> None:
    assert evaluate(Binary("/", IntLit(1), IntLit(0)), {}) == math.inf


def test_constants_in_dependency_order_and_given_values() -> None:
    model = flat(
        "dtmc\nconst int B = A + 1;\nconst int A;\nconst double p;\nconst bool f;\n"
        "module m x : [0..B] init A; endmodule\n",
        {"A": "2", "p": "1/4", "f": "true", "unused": "9"},
    )
    assert model.constants == (("B", 3), ("A", 2), ("p", 0.25), ("f", True))
    assert model.variables[0].low == 0 and model.variables[0].high == 3
    assert model.variables[0].init == 2


def test_given_values_may_be_python_values() -> None:
    model = flat(
        "dtmc\nconst double p;\nconst int n;\nmodule m x : bool; endmodule\n", {"p": 1, "n": 3}
    )
    assert model.constants == (("p", 1.0), ("n", 3))


@pytest.mark.parametrize(
    ("decl", "value", "message"),
    [
        ("const int n;", "1.5", "constant 'n' is an int, but was given the value '1.5'"),
        ("const bool n;", "1", "constant 'n' is a bool, but was given the value '1'"),
        ("const int n;", True, "constant 'n' is an int, but was given the value True"),
        ("const int n = 2;", "3", "constant 'n' is already defined"),
    ],
)
def test_given_value_of_wrong_type(decl: str, value: object, message: str) -> None:
    with pytest.raises(PrismSemanticError, match=message):
        flat(f"dtmc\n{decl}\nmodule m x : bool; endmodule\n", {"n": value})


INT_RANGE = ("is out of the int range -2^63..2^63-1 (ints are 64-bit here; PRISM's are "
             "32-bit): use a smaller int, or a double such as 1e19")


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("99999999999999999999",
         f"constant 'n' (--const n=99999999999999999999): 99999999999999999999 {INT_RANGE}"),
        ("2*4611686018427387904",
         f"constant 'n' (--const n=2*4611686018427387904): 9223372036854775808 {INT_RANGE}"),
        (-(2**63) - 1, f"constant 'n' (--const n=-9223372036854775809): "
                       f"-9223372036854775809 {INT_RANGE}"),
        # Beyond the 4,300 digits Python reads into an int: the same rule, quoted short
        # (was "is an int, but was given the value '9999...'", all 5,000 digits).
        ("9" * 5000, f"constant 'n' (--const n=999999999999…999999 (5,000 characters)): "
                     f"<5,000 digits> {INT_RANGE}"),
        ("-" + "9" * 5000, f"constant 'n' (--const n=-99999999999…999999 (5,001 characters)): "
                           f"<5,000 digits> {INT_RANGE}"),
    ],
)
def test_given_int_beyond_64_bits(value: object, message: str) -> None:
    with pytest.raises(PrismSemanticError) as info:
        flat("dtmc\nconst int n;\nmodule m x : bool; endmodule\n", {"n": value})
    assert str(info.value) == message


def test_int_constants_at_the_64_bit_limits() -> None:
    assert const_value("pow(2, 62) - 1 + pow(2, 62)", "int") == 2**63 - 1
    assert const_value("-pow(2, 62) - pow(2, 62)", "int") == -(2**63)
    assert const_value("pow(2, 62) * 4", "double") == 2.0**64  # a double may be larger


def test_defined_int_constant_beyond_64_bits() -> None:
    with pytest.raises(PrismSemanticError) as info:
        const_value("pow(2, 62) * 4", "int")
    assert str(info.value) == f"t.prism:2:15: constant 'c': 18446744073709551616 {INT_RANGE}"


def test_undefined_constant_not_given() -> None:
    text = "dtmc\nconst int N;\nconst int K = 2;\nconst double p;\nmodule m x : bool; endmodule\n"
    assert undefined_constants(parse_model(text)) == ("N", "p")
    with pytest.raises(PrismSemanticError) as info:
        flat(text)
    assert str(info.value) == (
        "t.prism:2:1: undefined constants N, p: give values with --const N=VALUE,p=VALUE, "
        "or constants={'N': VALUE, 'p': VALUE} from Python"
    )


def test_parse_constant_assignments() -> None:
    assert parse_constant_assignments(["N=16", "MAX=2,p=0.5", " x = true "]) == {
        "N": "16",
        "MAX": "2",
        "p": "0.5",
        "x": "true",
    }


def test_a_constant_may_be_given_as_a_closed_expression() -> None:
    """``--const p=1/3``: numbers, operators and functions; commas inside parentheses
    belong to the expression."""
    assert parse_constant_assignments(["M=max(2,3),N=4", "q=pow(2, -1.0)"]) == {
        "M": "max(2,3)", "N": "4", "q": "pow(2, -1.0)"}
    model = flat(
        "dtmc\nconst double p;\nconst int N;\nconst int M;\nconst double q;\nconst bool b;\n"
        "module m x : bool; endmodule\n",
        {"p": "1/3", "N": "2*3", "M": "max(2,3)", "q": "pow(2, -1.0)", "b": "1 < 2 & !false"},
    )
    assert model.constants == (("p", 1 / 3), ("N", 6), ("M", 3), ("q", 0.5), ("b", True))


@pytest.mark.parametrize(
    ("decl", "value", "message"),
    [
        ("const int n;", "2*x", "constant 'n' is an int, but was given the value '2\\*x'"),
        ("const int n;", "7/2", "constant 'n' is an int, but was given the value '7/2'"),
        ("const double n;", "1 +", "constant 'n' is a double, but was given the value '1 \\+'"),
        ("const double n;", '"a"', "constant 'n' is a double, but was given the value '\"a\"'"),
        ("const int n;", "mod(3, 0)", "constant 'n' has no value: --const n=mod\\(3, 0\\): "
                                      "cannot evaluate mod"),
    ],
)
def test_a_given_expression_must_be_closed_and_of_the_constant_type(
        decl: str, value: str, message: str) -> None:
    with pytest.raises(PrismSemanticError, match=message):
        flat(f"dtmc\n{decl}\nmodule m x : bool; endmodule\n", {"n": value})


@pytest.mark.parametrize("item", ["N", "N=", "=3", "1N=2", "N=1,,M=2"])
def test_malformed_constant_assignment(item: str) -> None:
    with pytest.raises(
        PrismSemanticError, match=r"malformed constant '.*' in --const .*NAME=VALUE"
    ):
        parse_constant_assignments([item])


def test_constant_given_twice() -> None:
    with pytest.raises(PrismSemanticError, match="'N' is given twice"):
        parse_constant_assignments(["N=1", "N=2"])


def test_formulas_are_inlined_through_formulas() -> None:
    model = flat(
        "dtmc\nconst int N = 2;\nformula g = f + 1;\nformula f = x * N;\n"
        "module m x : [0..4]; [] g < 4 -> (x'=min(g, 4)); endmodule\n"
    )
    guard = model.modules[0].commands[0].guard
    assert guard == Binary(
        "<", Binary("+", Binary("*", Ident("x"), IntLit(2)), IntLit(1)), IntLit(4)
    )
    assert [f.name for f in model.formulas] == ["g", "f"]


def test_constants_are_literals_and_folded() -> None:
    model = flat(
        MINI.replace("0.5:(x'=x+1) + 0.5", "p:(x'=x+1) + 1-p").replace(
            "const int N = 3;", "const int N = 3;\nconst double p = 0.25;"
        )
    )
    command = model.modules[0].commands[0]
    assert command.guard == Binary("<", Ident("x"), IntLit(3))
    probabilities = [u.probability for u in command.updates]
    assert all(isinstance(p, DoubleLit) for p in probabilities)
    assert [p.value for p in probabilities] == [0.25, 0.75]  # type: ignore[union-attr]


def test_flat_model_shape() -> None:
    model = flat(
        "dtmc\nglobal g : bool init true;\nmodule a x : [1..3]; [s] x<3 -> (x'=x+1); "
        "[] true -> (g'=false); endmodule\n"
        "module b y : [0..1] init 1; [s] true -> true; endmodule\n"
        'label "l" = x=2;\nrewards "r" [s] true : 1; endrewards\n'
    )
    assert [(v.name, v.low, v.high, v.init, v.is_bool, v.module) for v in model.variables] == [
        ("g", 0, 1, 1, True, None),
        ("x", 1, 3, 1, False, "a"),
        ("y", 0, 1, 1, False, "b"),
    ]
    assert model.variable_names == ("g", "x", "y")
    assert [(m.name, m.variables, m.alphabet) for m in model.modules] == [
        ("a", ("x",), frozenset({"s"})),
        ("b", ("y",), frozenset({"s"})),
    ]
    assert model.labels[0].name == "l" and model.rewards[0].name == "r"
    assert model.init is None


def test_init_block() -> None:
    model = flat("dtmc\nmodule m x : [0..2]; endmodule\ninit x > 0 endinit\n")
    assert model.init == Binary(">", Ident("x"), IntLit(0))
    with pytest.raises(PrismSemanticError, match=r"t\.prism:2:26: variable 'x' has an init value"):
        flat("dtmc\nmodule m x : [0..2] init 1; endmodule\ninit x > 0 endinit\n")


def test_renaming_renames_variables_actions_and_constants() -> None:
    model = flat(
        "dtmc\nconst int A = 1;\nconst int B = 2;\nformula nxt = x + A;\n"
        "module m x : [0..5]; [go] x < 5 -> (x'=min(nxt, 5)); endmodule\n"
        "module n = m [x=y, go=stop, A=B] endmodule\n"
    )
    second = model.modules[1]
    assert second.variables == ("y",) and second.alphabet == frozenset({"stop"})
    update = second.commands[0].updates[0].assignments[0]
    assert update.variable == "y"
    # The formula was expanded before renaming, so its x and A were renamed too.
    assert str(update.expr) == str(
        model.modules[0].commands[0].updates[0].assignments[0].expr
    ).replace("'x'", "'y'").replace("value=1", "value=2")


@pytest.mark.skipif(not PEER.exists(), reason="peer suites not found")
def test_herman_renaming_is_simultaneous() -> None:
    path = PEER / "prism-examples/prism-examples/dtmcs/herman/herman5.pm"
    model = flatten_model(parse_model(path))
    guards = [m.commands[0].guard for m in model.modules]
    pairs = [(g.left.name, g.right.name) for g in guards]  # type: ignore[union-attr]
    assert pairs == [("x1", "x5"), ("x2", "x1"), ("x3", "x2"), ("x4", "x3"), ("x5", "x4")]
    assert model.init is not None and len(model.variables) == 5


def error(text: str) -> str:
    with pytest.raises(PrismSemanticError) as info:
        flat(text)
    return str(info.value)


def test_unknown_identifier() -> None:
    text = MINI.replace("0.5:(x'=x)", "0.5:(x'=y)")
    assert error(text) == "t.prism:5:37: unknown identifier 'y'"


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "(x'=x+1)",
            "(x'=true)",
            "t.prism:5:18: type error: cannot assign bool to int variable 'x'",
        ),
        (
            "(x'=x+1)",
            "(x'=x/2)",
            "t.prism:5:18: type error: cannot assign double to int variable 'x'",
        ),
        ("x<N ->", "x+N ->", "t.prism:5:7: type error: a guard must be a bool, not int"),
        (
            "0.5:(x'=x)",
            "true:(x'=x)",
            "t.prism:5:29: type error: a probability must be a number, not bool",
        ),
        (
            "x<N ->",
            "x<true ->",
            "t.prism:5:7: type error: operator '<' cannot be applied to int and bool",
        ),
    ],
)
def test_type_errors(old: str, new: str, message: str) -> None:
    assert error(MINI.replace(old, new)).startswith(message)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ("const int N = 4;\n", "t.prism:7:1: duplicate name 'N' (first defined at t.prism:2:1)"),
        ("formula N = 1;\n", "t.prism:7:1: duplicate name 'N'"),
        ("module m y : bool; endmodule\n", "t.prism:7:1: duplicate module 'm'"),
        ("module k x : bool; endmodule\n", "t.prism:7:10: duplicate name 'x'"),
        ('label "a" = true;\nlabel "a" = false;\n', "t.prism:8:1: duplicate label 'a'"),
        (
            'rewards "r" true : 1; endrewards\nrewards "r" true : 2; endrewards\n',
            "t.prism:8:1: duplicate reward structure 'r'",
        ),
    ],
)
def test_duplicate_names(extra: str, message: str) -> None:
    assert error(MINI + extra).startswith(message)


def test_module_updating_another_modules_variable() -> None:
    text = MINI + "module k\n  y : bool;\n  [] true -> (x'=0);\nendmodule\n"
    assert error(text) == "t.prism:9:14: Module k cannot modify variable x of module m"


def test_global_updated_in_synchronised_command() -> None:
    text = MINI.replace("module m", "global g : bool;\nmodule m").replace("(x'=x)", "(g'=true)")
    assert error(text).startswith("t.prism:6:33: global variable 'g' cannot be updated")


def test_same_variable_assigned_twice() -> None:
    text = MINI.replace("(x'=x)", "(x'=x)&(x'=0)")
    assert error(text).startswith("t.prism:5:40: duplicate assignment to 'x'")


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("[0..N]", "[N..0]", "t.prism:4:3: variable 'x' has an empty range [3..0]"),
        ("init 0", "init 7", "t.prism:4:3: initial value 7 of 'x' is outside its range [0..3]"),
        ("[0..N]", "[0..N/2]", "type error: the upper bound of 'x' must be an int"),
        ("[0..N]", "[0..10000000000000000000000]",
         "t.prism:4:3: variable 'x' has the range [0..10000000000000000000000], too wide for "
         "the 64-bit ints states are stored in: its bounds must lie in -2^63..2^63-1, and it "
         "must hold fewer than 2^63 values"),
        ("[0..N]", "[0..pow(2,62)*2-1]", "[0..9223372036854775807], too wide"),
        ("[0..N]", "[-pow(2,62)..pow(2,62)]", "[-4611686018427387904..4611686018427387904], too"),
        ("[0..N]", "[-pow(2,62)*2-1..0]", "[-9223372036854775809..0], too wide"),
        ("[0..N]", f"[0..{10**39}]", f"[0..{10**39}], too wide"),  # 40 digits: shown
        ("[0..N]", f"[0..{10**40}]", "[0..<41 digits>], too wide"),
    ],
)
def test_range_errors(old: str, new: str, message: str) -> None:
    assert message in error(MINI.replace(old, new))


@pytest.mark.parametrize("bounds", ["[0..pow(2,62)*2-2]", "[-pow(2,62)*2..-2]",
                                    "[pow(2,62)*2-2..pow(2,62)*2-1]"])
def test_ranges_at_the_64_bit_limits(bounds: str) -> None:
    low = bounds[1:].split("..")[0]
    model = flat(MINI.replace("[0..N] init 0", f"{bounds} init {low}"))
    assert model.variables[0].high - model.variables[0].low <= 2**63 - 2


def test_cyclic_formulas() -> None:
    assert "cyclic formula definition: f -> g -> f" in error(
        MINI + "formula f = g;\nformula g = f;\n"
    )


def test_renaming_an_unknown_module() -> None:
    assert "module 'q' (renamed as 'n') is not defined" in error(
        MINI + "module n = q [x=y] endmodule\n"
    )


def test_model_file_path_in_messages(tmp_path: Path) -> None:
    path = tmp_path / "bad.prism"
    path.write_text(MINI.replace("(x'=x)", "(x'=zz)"))
    with pytest.raises(PrismSemanticError, match=f"^{path}:5:37: unknown identifier 'zz'$"):
        flatten_model(parse_model(path))


LABELLED = ('dtmc\nmodule m x : [0..3]; [] x<3 -> (x\'=x+1); endmodule\n'
            'label "top" = x=3;\n')


def test_a_label_may_refer_to_another_label() -> None:
    # PRISM allows a declared label in a label's definition (ModulesFileSemanticCheck).
    model = flat(LABELLED + 'label "near" = "top" | x=2;\nlabel "far" = !"near";\n')
    labels = {lab.name: lab.expr for lab in model.labels}
    assert [evaluate(labels["near"], {"x": x}) for x in range(4)] == [False, False, True, True]
    assert [evaluate(labels["far"], {"x": x}) for x in range(4)] == [True, True, False, False]


@pytest.mark.parametrize(("labels", "message"), [
    ('label "a" = "b";\nlabel "b" = "a";\n', 'labels refer to themselves: "a" -> "b" -> "a"'),
    ('label "a" = "a" | x=1;\n', 'labels refer to themselves: "a" -> "a"'),
    ('label "a" = "nosuch";\n', 'undeclared label "nosuch" (labels: "top", "a")'),
])
def test_a_label_refers_to_a_declared_label_without_a_cycle(labels: str, message: str) -> None:
    with pytest.raises(PrismSemanticError) as info:
        flat(LABELLED + labels)
    assert message in str(info.value)
