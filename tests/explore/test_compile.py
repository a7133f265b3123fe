"""compile_expr: PRISM expression semantics over many states at once."""

from __future__ import annotations

import numpy as np
import pytest

from tests.explore.models import expr
from veribattery.errors import ModelError, PrismSemanticError, Span
from veribattery.explore import compile_expr
from veribattery.explore.compile.bounds import value_bounds
from veribattery.explore.compile.expr import CompileCache, constant_value
from veribattery.lang.nodes import Binary, DoubleLit, Eventually, Ident, IntLit, LabelRef, ProbOp

NAMES = ("x", "y")
STATES = np.array([[0, 3], [2, 5], [-3, 4], [7, -2]], dtype=np.int64)


def run(text: str, states: np.ndarray = STATES) -> np.ndarray:
    return compile_expr(expr(text), NAMES)(states)


@pytest.mark.parametrize(
    ("text", "expected", "kind"),
    [
        ("x + y * 2", [6, 12, 5, 3], "i"),
        ("y / 2", [1.5, 2.5, 2.0, -1.0], "f"),
        ("4 / 2", [2.0] * 4, "f"),
        ("floor(y / 2)", [1, 2, 2, -1], "i"),
        ("ceil(y / 2)", [2, 3, 2, -1], "i"),
        ("mod(x, 3)", [0, 2, 0, 1], "i"),  # PRISM: result in 0..b-1 even for negative x
        ("pow(y, 2)", [9, 25, 16, 4], "i"),
        ("pow(2, 0.5)", [2**0.5] * 4, "f"),
        ("min(x, y)", [0, 2, -3, -2], "i"),
        ("max(x, y, 1)", [3, 5, 4, 7], "i"),
        ("max(x, 0.5)", [0.5, 2.0, 0.5, 7.0], "f"),
        ("log(8, 2)", [3.0] * 4, "f"),
        ("x > 1 ? x : -1", [-1, 2, -1, 7], "i"),
        ("x = 2 | y = 4", [False, True, True, False], "b"),
        ("x > 0 => y > 4", [True, True, True, False], "b"),
        ("x > 0 <=> y > 0", [False, True, False, False], "b"),
        ("!(x = 0) & y != 4", [False, True, False, True], "b"),
        ("y / 2 = 2.5", [False, True, False, False], "b"),  # int/float compare numerically
        ("-x", [0, -2, 3, -7], "i"),
        ("1 + 2", [3] * 4, "i"),
        ("true", [True] * 4, "b"),
    ],
)
def test_semantics(text: str, expected: list[object], kind: str) -> None:
    result = run(text)
    assert result.shape == (4,)
    assert result.dtype.kind == kind
    assert result.tolist() == pytest.approx(expected)


def test_integers_stay_exact() -> None:
    big = np.array([[2**53 + 1, 1]], dtype=np.int64)
    assert run("x + y", big)[0] == 2**53 + 2


def test_risky_operands_only_evaluated_where_needed() -> None:
    # Division by zero would occur where x = 0, but those rows are excluded.
    assert run("x != 0 & y / x > 1").tolist() == [False, True, False, False]
    assert run("x = 0 ? 0 : y / x").tolist() == pytest.approx([0, 2.5, -4 / 3, -2 / 7])
    assert run("x = 0 | y / x > 1").tolist() == [True, True, False, False]


@pytest.mark.parametrize(
    ("text", "expected"),
    [("false & pow(0, -1) = 0", False), ("true | pow(0, -1) = 0", True),
     ("false => pow(0, -1) = 0", True), ("x > 9 | (false & mod(1, 0) = 0)", False)],
)
def test_a_constant_left_operand_short_circuits(text: str, expected: bool) -> None:
    """PRISM never evaluates the right operand a constant left one decides, even when
    folding it would fail (found by test_operator_agreement)."""
    assert run(text).tolist() == [expected] * 4


def test_division_by_zero_is_infinite_as_in_java() -> None:
    """PRISM divides doubles: y/0 is +-inf by the signs, 0/0 NaN; no error."""
    got = run("y / (x - x)")
    assert got.tolist() == [np.inf, np.inf, np.inf, -np.inf]
    assert np.isnan(run("x / (y - y)")[0])
    assert run("y / (x - x) > 100").tolist() == [True, True, True, False]


def test_floor_of_an_infinite_quotient_is_a_model_error() -> None:
    with pytest.raises(ModelError, match="cannot take floor of inf"):
        run("floor(y / x)")
    assert run("x != 0 & floor(y / x) >= 0").tolist() == [False, True, False, False]


@pytest.mark.parametrize(
    ("text", "message"),
    [("mod(y, x)", "non-positive divisor"), ("pow(2, x)", "negative exponent")],
)
def test_integer_function_errors(text: str, message: str) -> None:
    with pytest.raises(ModelError, match=message):
        run(text)


def test_constant_division_by_zero_in_untaken_branch_is_fine() -> None:
    assert run("true ? 1 : 1 / 0").tolist() == [1, 1, 1, 1]


def test_unknown_identifier_has_span() -> None:
    with pytest.raises(PrismSemanticError, match="unknown identifier 'z'") as info:
        compile_expr(Ident("z", Span(3, 7, "m.pm")), NAMES)
    assert info.value.span == Span(3, 7, "m.pm")


def test_labels_and_unknown_label() -> None:
    masks = {"goal": np.array([True, False, True, False])}
    fn = compile_expr(LabelRef("goal"), NAMES, masks)
    assert fn(STATES).tolist() == [True, False, True, False]
    with pytest.raises(PrismSemanticError, match='unknown label "other"'):
        compile_expr(LabelRef("other", Span(1, 2)), NAMES, masks)


def test_property_operators_are_rejected() -> None:
    node = ProbOp("=?", None, Eventually(Ident("x")), Span(2, 1))
    with pytest.raises(PrismSemanticError, match="not allowed"):
        compile_expr(node, NAMES)


def test_no_rows() -> None:
    assert run("x + 1", np.empty((0, 2), dtype=np.int64)).shape == (0,)
    assert run("3", np.empty((0, 2), dtype=np.int64)).shape == (0,)


@pytest.mark.parametrize(
    ("text", "bounds"),
    [
        ("min(x + 1, 5)", (1.0, 5.0)),
        ("max(x - 1, 0)", (0.0, 4.0)),
        ("x > 2 ? x : 0", (0.0, 5.0)),
        ("2 * x - y", (-10.0, 10.0)),
        ("x / 2", None),
        ("mod(x, 2)", None),
    ],
)
def test_value_bounds(text: str, bounds: tuple[float, float] | None) -> None:
    assert value_bounds(expr(text), {"x": (0.0, 5.0), "y": (0.0, 10.0)}) == bounds


def test_constant_value() -> None:
    assert constant_value(expr("1 / 4 + 0.5"), NAMES) == 0.75
    assert constant_value(expr("x + 1"), NAMES) is None


RANGE_MESSAGE = ("is out of the int range -2^63..2^63-1 (ints are 64-bit here; PRISM's are "
                 "32-bit): use a smaller int, or a double such as 1e19")


@pytest.mark.parametrize("value", [2**63, -(2**63) - 1, 10**22, 10**320])
@pytest.mark.parametrize("cached", [False, True])
def test_int_literal_beyond_64_bits(value: int, cached: bool) -> None:
    literal = IntLit(value, Span(3, 7, "m.pm"))
    node = Binary("=", Ident("x"), literal)
    cache = CompileCache() if cached else None  # its key of a huge int is no float
    with pytest.raises(PrismSemanticError) as info:
        compile_expr(node, NAMES, cache=cache)
    shown = str(value) if value < 10**40 else "<321 digits>"
    assert str(info.value) == f"m.pm:3:7: {shown} {RANGE_MESSAGE}"


@pytest.mark.parametrize("value", [2**63 - 1, -(2**63)])
def test_int_literals_at_the_64_bit_limits(value: int) -> None:
    fn = compile_expr(Binary("+", Ident("x"), IntLit(value)), NAMES, cache=CompileCache())
    assert fn(np.zeros((1, 2), dtype=np.int64)).tolist() == [value]


def test_cache_keys_tell_the_zeros_of_doubles_apart() -> None:
    cache = CompileCache()
    assert cache.key(DoubleLit(0.0, "0.0")) != cache.key(DoubleLit(-0.0, "-0.0"))
    assert cache.key(IntLit(10**400)) == cache.key(IntLit(10**400))
    assert cache.key(IntLit(10**400)) != cache.key(IntLit(-(10**400)))
