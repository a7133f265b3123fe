"""The evaluators of PRISM's operators agree with each other and with PRISM.

One table (:mod:`veribattery.lang.ops`) defines the operators; five places evaluate
them: constant evaluation (:mod:`veribattery.lang.evaluate`), constant folding
(:func:`veribattery.lang.expressions.close`), the builder's numpy kernels
(:func:`veribattery.explore.compile.expr.compile_expr`, row by row and tabulated), exact
rationals (:func:`veribattery.explore.exact.rational.evaluate_rational`) and the checker's
intervals (:mod:`veribattery.checker.formula.intervals`). Random expressions over ints,
doubles and bools are evaluated by each and compared with a reference written
here (a plain recursive walk over the table), state by state; then each case the
issue lists is checked against the value PRISM gives, written out by hand.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from fractions import Fraction
from typing import Any

import numpy as np
import pytest
from gmpy2 import mpq
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from veribattery.checker.certify.bounds import Bounds
from veribattery.checker.formula import intervals
from veribattery.errors import CheckError, ModelError, VeribatteryError
from veribattery.explore.compile.expr import CompileCache, compile_expr
from veribattery.explore.exact.rational import evaluate_rational
from veribattery.lang import ops, parse_property
from veribattery.lang.evaluate import EvaluationError, evaluate
from veribattery.lang.expressions import close
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    DoubleLit,
    Expr,
    Ident,
    IntLit,
    Ite,
    Unary,
    Value,
    ValueType,
)
from veribattery.lang.typecheck import TypeEnv, type_of

# ---------------------------------------------------------------------------
# Random expressions over the variables i, j (ints) and b (a bool)
# ---------------------------------------------------------------------------

NAMES = ("i", "j", "b")
TYPES: dict[str, ValueType] = {"i": "int", "j": "int", "b": "bool"}
RANGES = {"i": (-3, 4), "j": (-3, 4), "b": (0, 1)}
DOUBLES = (0.0, 0.5, -1.5, 2.0, 0.25, 3.0, -0.0, 1.0)


def _double(value: float) -> Expr:
    return DoubleLit(value, repr(value))


_LEAVES: dict[str, st.SearchStrategy[Expr]] = {
    "int": st.one_of(st.integers(-4, 6).map(IntLit), st.sampled_from([Ident("i"), Ident("j")])),
    "double": st.sampled_from(DOUBLES).map(_double),
    "bool": st.one_of(st.booleans().map(BoolLit), st.just(Ident("b"))),
}


def _call(func: str) -> Callable[..., Expr]:
    return lambda *args: Call(func, tuple(args))  # type: ignore[arg-type]


def _calls(func: str, args: st.SearchStrategy[list[Expr]]) -> st.SearchStrategy[Expr]:
    return args.map(lambda xs: Call(func, tuple(xs)))  # type: ignore[arg-type]


@functools.cache
def expressions(kind: str, depth: int) -> st.SearchStrategy[Expr]:
    """Well-typed expressions of type *kind*, at most *depth* operators deep."""
    if depth == 0:
        return _LEAVES[kind]
    def sub(k: str) -> st.SearchStrategy[Expr]:
        return expressions(k, depth - 1)
    number = st.one_of(sub("int"), sub("double"))
    compound = {"int": _int_forms, "double": _double_forms, "bool": _bool_forms}[kind]
    return st.one_of(_LEAVES[kind], *compound(sub, number))


def _int_forms(sub: Any, number: Any) -> list[st.SearchStrategy[Expr]]:
    ints = sub("int")
    return [
        st.builds(Unary, st.just("-"), ints),
        st.builds(Binary, st.sampled_from(["+", "-", "*"]), ints, ints),
        st.builds(lambda f, x: Call(f, (x,)), st.sampled_from(["floor", "ceil", "round"]),
                  number),
        st.builds(_call("pow"), ints, ints),
        st.builds(_call("mod"), ints, ints),
        _calls("min", st.lists(ints, min_size=1, max_size=3)),
        _calls("max", st.lists(ints, min_size=1, max_size=3)),
        st.builds(Ite, sub("bool"), ints, ints),
    ]


def _double_forms(sub: Any, number: Any) -> list[st.SearchStrategy[Expr]]:
    doubles = sub("double")
    mixed = st.lists(number, min_size=0, max_size=2)
    return [
        st.builds(Unary, st.just("-"), doubles),
        st.builds(Binary, st.sampled_from(["+", "-", "*"]), doubles, number),
        st.builds(Binary, st.sampled_from(["+", "-", "*"]), number, doubles),
        st.builds(Binary, st.just("/"), number, number),
        st.builds(_call("pow"), doubles, number),
        st.builds(_call("pow"), number, doubles),
        st.builds(_call("log"), number, number),
        st.builds(lambda f, d, xs: Call(f, (*xs, d)), st.sampled_from(["min", "max"]),
                  doubles, mixed),
        st.builds(Ite, sub("bool"), doubles, number),
        st.builds(Ite, sub("bool"), sub("int"), doubles),
    ]


def _bool_forms(sub: Any, number: Any) -> list[st.SearchStrategy[Expr]]:
    bools = sub("bool")
    return [
        st.builds(Unary, st.just("!"), bools),
        st.builds(Binary, st.sampled_from(["&", "|", "=>", "<=>", "=", "!="]), bools, bools),
        st.builds(Binary, st.sampled_from(["=", "!=", "<", "<=", ">", ">="]), number, number),
        st.builds(Ite, bools, bools, bools),
    ]


STATES = st.lists(st.tuples(st.integers(-3, 4), st.integers(-3, 4), st.booleans()),
                  min_size=1, max_size=6)

# ---------------------------------------------------------------------------
# The reference: a recursive walk over the table, noting what PRISM's doubles do
# ---------------------------------------------------------------------------


class Walk:
    """One evaluation of the reference, and what it met on the way."""

    def __init__(self, values: dict[str, Value], types: dict[str, ValueType]) -> None:
        self.values, self.env = values, TypeEnv(types)
        self.value: Value = False  # the result, once walked
        self.nonfinite = False  # a value was infinite or NaN (no exact rational)
        self.inexact = False  # a double operation rounded, or has an irrational value

    def __call__(self, expr: Expr) -> Value:
        value = self._value(expr)
        if isinstance(value, float) and not math.isfinite(value):
            self.nonfinite = True
        return value

    def _value(self, expr: Expr) -> Value:
        if isinstance(expr, IntLit | DoubleLit | BoolLit):
            return expr.value
        if isinstance(expr, Ident):
            return self.values[expr.name]
        if isinstance(expr, Unary):
            return ops.UNARY[expr.op].apply(self(expr.operand))
        if isinstance(expr, Binary):
            return self._binary(expr)
        if isinstance(expr, Ite):
            value = self(expr.then if self(expr.cond) else expr.otherwise)
            double = type_of(expr, self.env) == "double"
            return float(value) if double else value
        assert isinstance(expr, Call)
        args = [self(a) for a in expr.args]
        value = ops.FUNCTIONS[expr.func].apply(*args)
        self._note(expr.func, args, value)
        return value

    def _binary(self, expr: Binary) -> Value:
        op = ops.BINARY[expr.op]
        left = self(expr.left)
        if op.lazy:
            decided = ops.decided_by(expr.op, bool(left))
            if decided is not None:
                return decided
        right = self(expr.right)
        value = op.apply(left, right)
        self._note(expr.op, [left, right], value)
        return value

    def _note(self, name: str, args: list[Value], value: Value) -> None:
        """Whether a double *value* is not the exact value of *name* on *args*."""
        exact = _exact(name, args)
        if exact is None:
            return
        rounded = isinstance(value, float) and math.isfinite(value) and Fraction(value) != exact
        if exact is _IRRATIONAL or rounded:
            self.inexact = True


_IRRATIONAL = object()


def _exact(name: str, args: list[Value]) -> Any:
    """The exact value of a double operation on finite operands, if it may round."""
    if not all(isinstance(a, int | float) and math.isfinite(a) for a in args):
        return None
    xs = [Fraction(a) for a in args]
    if name in ("+", "-", "*"):
        return {"+": xs[0] + xs[1], "-": xs[0] - xs[1], "*": xs[0] * xs[1]}[name]
    if name == "/":
        return xs[0] / xs[1] if xs[1] else None
    if name == "log":
        return _IRRATIONAL
    if name == "pow" and not all(isinstance(a, int) for a in args):
        if xs[1].denominator != 1 or abs(xs[1]) > 64:
            return _IRRATIONAL  # or too large to compare: no exact value to expect
        return None if xs[0] == 0 and xs[1] < 0 else xs[0] ** int(xs[1])
    return None


def _same(expected: Value, got: Any, kind: ValueType) -> bool:
    """*got* (a numpy, mpq or Python scalar) is *expected*, bit for bit for doubles."""
    if kind == "bool":
        return bool(got) == expected
    if kind == "int":
        return bool(int(got) == expected)
    value, want = float(got), float(expected)
    if math.isnan(want):
        return math.isnan(value)
    return value == want and math.copysign(1, value) == math.copysign(1, want)


def _references(expr: Expr, rows: list[tuple[int, int, bool]]) -> list[Walk | OperatorFailure]:
    out: list[Walk | OperatorFailure] = []
    for i, j, b in rows:
        walk = Walk({"i": i, "j": j, "b": b}, TYPES)
        try:
            walk.value = walk(expr)
        except ops.OperatorError as exc:
            out.append(OperatorFailure(str(exc)))
            continue
        out.append(walk)
    return out


class OperatorFailure:
    """The reference has no value: PRISM reports an error."""

    def __init__(self, message: str) -> None:
        self.message = message


def _state_array(rows: list[tuple[int, int, bool]]) -> np.ndarray:
    return np.array([[i, j, int(b)] for i, j, b in rows], dtype=np.int64)


# ---------------------------------------------------------------------------
# The property
# ---------------------------------------------------------------------------


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_every_evaluator_agrees_with_the_reference(data: st.DataObject) -> None:
    kind: ValueType = data.draw(st.sampled_from(["int", "double", "bool"]), label="type")
    expr = data.draw(expressions(kind, 3), label="expression")
    rows = data.draw(STATES, label="states")
    assert type_of(expr, TypeEnv(TYPES)) == kind
    refs = _references(expr, rows)
    failed = any(isinstance(r, OperatorFailure) for r in refs)
    for (i, j, b), ref in zip(rows, refs, strict=True):
        _check_scalar(expr, {"i": i, "j": j, "b": b}, ref, kind)
    _check_arrays(expr, rows, refs, kind, failed)
    _check_rationals(expr, rows, refs, kind, failed)


def _check_scalar(expr: Expr, values: dict[str, Value], ref: Walk | OperatorFailure,
                  kind: ValueType) -> None:
    """``evaluate`` and constant folding, in one state."""
    folded = close(expr, values, TYPES, {})
    if isinstance(ref, OperatorFailure):
        with pytest.raises(EvaluationError):
            evaluate(expr, values)
        assert not isinstance(folded, IntLit | DoubleLit | BoolLit)
        with pytest.raises(EvaluationError):
            evaluate(folded, {})
        return
    expected = ref.value
    got = evaluate(expr, values)
    assert type(got) is type(expected) and _same(expected, got, kind)
    assert _same(expected, evaluate(folded, {}), kind)
    if isinstance(folded, DoubleLit):
        assert kind == "double"


def _check_arrays(expr: Expr, rows: list[tuple[int, int, bool]],
                  refs: list[Walk | OperatorFailure], kind: ValueType, failed: bool) -> None:
    """The builder's kernels, row-wise and tabulated: one error where the reference
    fails in some state (and only then), else the same values bit for bit."""
    states = _state_array(rows)
    for ranges in (None, RANGES):
        compiled = compile_expr(expr, NAMES, ranges=ranges, cache=CompileCache())
        if failed:
            with pytest.raises(ModelError):
                compiled(states)
            continue
        got = compiled(states)
        # (a boolean variable is a 0/1 int column)
        assert got.dtype.kind in {"int": "i", "double": "f", "bool": "bi"}[kind]
        for value, ref in zip(got, refs, strict=True):
            assert _same(ref.value, value, kind)  # type: ignore[union-attr]


def _check_rationals(expr: Expr, rows: list[tuple[int, int, bool]],
                     refs: list[Walk | OperatorFailure], kind: ValueType, failed: bool) -> None:
    """Exact rationals: the exact value where the doubles are exact, an error only
    where the reference fails or has no exact value (an infinity, a log)."""
    columns = {"i": _objects([mpq(r[0]) for r in rows]), "j": _objects([mpq(r[1]) for r in rows]),
               "b": np.array([r[2] for r in rows], dtype=bool)}
    soft = any(isinstance(r, Walk) and (r.nonfinite or r.inexact) for r in refs)
    try:
        got = evaluate_rational(expr, {}, columns, len(rows))
    except ModelError:
        assert failed or soft
        return
    assert not failed
    for value, ref in zip(got, refs, strict=True):
        assert isinstance(ref, Walk)
        if not (ref.nonfinite or ref.inexact):
            expected = ref.value
            if kind == "bool":
                assert bool(value) == expected
            else:
                assert Fraction(int(value.numerator), int(value.denominator)) == Fraction(expected)


def _objects(items: list[Any]) -> np.ndarray:
    array = np.empty(len(items), dtype=object)
    array[:] = items
    return array


# ---------------------------------------------------------------------------
# Intervals: the checker's arithmetic over operator results (doubles)
# ---------------------------------------------------------------------------


@functools.cache
def numbers(depth: int) -> st.SearchStrategy[Expr]:
    """Double expressions without conditions: the checker's arithmetic over results."""
    leaves = st.one_of(st.sampled_from((*DOUBLES, 3.5, -2.25)).map(_double),
                       st.sampled_from([Ident("x"), Ident("y")]))
    if depth == 0:
        return leaves
    sub = numbers(depth - 1)
    return st.one_of(
        leaves,
        st.builds(Unary, st.just("-"), sub),
        st.builds(Binary, st.sampled_from(["+", "-", "*", "/"]), sub, sub),
        st.builds(lambda f, x: Call(f, (x,)), st.sampled_from(["floor", "ceil", "round"]), sub),
        st.builds(lambda f, x, y: Call(f, (x, y)), st.sampled_from(["pow", "log"]), sub, sub),
        _calls("min", st.lists(sub, min_size=1, max_size=3)),
        _calls("max", st.lists(sub, min_size=1, max_size=3)),
    )


def _intervals(expr: Expr, leaves: dict[str, Bounds]) -> Bounds:
    if isinstance(expr, DoubleLit):
        return Bounds.exact(np.full(len(leaves["x"].value), expr.value))
    if isinstance(expr, Ident):
        return leaves[expr.name]
    if isinstance(expr, Unary):
        return intervals.unary(expr.op, _intervals(expr.operand, leaves))  # type: ignore[return-value]
    if isinstance(expr, Binary):
        left, right = _intervals(expr.left, leaves), _intervals(expr.right, leaves)
        return intervals.binary(expr.op, left, right)  # type: ignore[return-value]
    assert isinstance(expr, Call)
    args = [_intervals(a, leaves) for a in expr.args]
    return intervals.call(expr.func, args)  # type: ignore[return-value]


@settings(max_examples=300, deadline=None)
@given(expr=numbers(3), xs=st.lists(st.tuples(st.sampled_from(DOUBLES), st.integers(-3, 4)),
                                   min_size=1, max_size=5))
def test_intervals_hold_the_point_value_and_the_exact_value(
        expr: Expr, xs: list[tuple[float, int]]) -> None:
    types: dict[str, ValueType] = {"x": "double", "y": "double"}
    refs = []
    for x, y in xs:
        walk = Walk({"x": x, "y": float(y)}, types)
        try:
            walk.value = walk(expr)
            refs.append(walk)
        except ops.OperatorError:
            refs.append(None)
    leaves = {"x": Bounds.exact(np.array([x for x, _ in xs])),
              "y": Bounds.exact(np.array([float(y) for _, y in xs]))}
    if any(r is None for r in refs):
        with pytest.raises(CheckError):
            _intervals(expr, leaves)
        return
    got = _intervals(expr, leaves)
    columns = {"x": _objects([mpq(Fraction(x)) for x, _ in xs]),
               "y": _objects([mpq(y) for _, y in xs])}
    try:
        exact: Any = evaluate_rational(expr, {}, columns, len(xs))
    except VeribatteryError:
        exact = [None] * len(xs)
    for k, ref in enumerate(refs):
        assert ref is not None
        assert _same(ref.value, got.value[k], "double")  # type: ignore[attr-defined]
        low, high, point = got.lower[k], got.upper[k], got.value[k]
        if not math.isnan(point):
            assert low <= point <= high
        if exact[k] is not None and not ref.nonfinite:
            value = Fraction(int(exact[k].numerator), int(exact[k].denominator))
            assert low == -math.inf or Fraction(low) <= value
            assert high == math.inf or value <= Fraction(high)


# ---------------------------------------------------------------------------
# The cases of the issue, with PRISM's values written out by hand
# ---------------------------------------------------------------------------

NAN = math.nan
INF = math.inf
ERROR = "error"

#: (expression over c, c, PRISM's value or ERROR, its type)
CASES: list[tuple[str, int, Any, ValueType]] = [
    # / always divides doubles; by zero it is infinite or NaN, never an error
    ("22/7", 0, 22 / 7, "double"),
    ("7/2", 0, 3.5, "double"),
    ("4/2", 0, 2.0, "double"),
    ("c/0", 3, INF, "double"),
    ("-c/0", 3, -INF, "double"),
    ("c/0", 0, NAN, "double"),
    ("1/c > 100", 0, True, "bool"),
    # mod: ints, a positive divisor, never negative
    ("mod(7, 3)", 0, 1, "int"),
    ("mod(-7, 3)", 0, 2, "int"),
    ("mod(c - 1, 5)", 0, 4, "int"),
    ("mod(7, -3)", 0, ERROR, "int"),
    ("mod(7, c)", 0, ERROR, "int"),
    # pow: an int of ints (no negative exponent), Java's Math.pow otherwise
    ("pow(2, 3)", 0, 8, "int"),
    ("pow(-2, 3)", 0, -8, "int"),
    ("pow(0, 0)", 0, 1, "int"),
    ("pow(2, -1)", 0, ERROR, "int"),
    ("pow(2, c - 1)", 0, ERROR, "int"),
    ("pow(2, -1.0)", 0, 0.5, "double"),
    ("pow(2.0, -1)", 0, 0.5, "double"),
    ("pow(9.0, 0.5)", 0, 3.0, "double"),
    ("pow(-8, 0.5)", 0, NAN, "double"),
    ("pow(0.0, -1)", 0, INF, "double"),
    ("pow(2, 62)", 0, 2**62, "int"),
    ("pow(2, 63)", 0, ERROR, "int"),
    ("pow(1.0, 0/0)", 0, NAN, "double"),
    # floor, ceil, round: ints; round halves up
    ("floor(-1.5)", 0, -2, "int"),
    ("ceil(-1.5)", 0, -1, "int"),
    ("floor(7)", 0, 7, "int"),
    ("round(2.5)", 0, 3, "int"),
    ("round(-1.5)", 0, -1, "int"),
    ("round(-2.5)", 0, -2, "int"),
    ("round(0.49999999999999994)", 0, 0, "int"),
    ("round(c / 2)", 3, 2, "int"),
    ("floor(1/c)", 0, ERROR, "int"),
    ("round(0/0)", 0, ERROR, "int"),
    ("ceil(pow(10.0, 30))", 0, ERROR, "int"),
    # log(x, b)
    ("log(8, 2)", 0, 3.0, "double"),
    ("log(1, 10)", 0, 0.0, "double"),
    ("log(0, 2)", 0, -INF, "double"),
    ("log(-1, 2)", 0, NAN, "double"),
    ("log(2, 1)", 0, NAN, "double"),
    ("log(2, 0)", 0, NAN, "double"),
    ("log(2, -2)", 0, NAN, "double"),
    ("log(2, 1/0)", 0, NAN, "double"),
    # min and max: one or more numbers, an int iff all are
    ("min(3)", 0, 3, "int"),
    ("max(c)", 2, 2, "int"),
    ("max(2, 3)", 0, 3, "int"),
    ("min(1, 2.5)", 0, 1.0, "double"),
    ("max(1, 2.5, c)", 4, 4.0, "double"),
    ("min(1/0, 2)", 0, 2.0, "double"),
    ("max(0/0, 1)", 0, NAN, "double"),
    ("1/min(0.0, -0.0)", 0, -INF, "double"),
    ("1/max(-0.0, 0.0)", 0, INF, "double"),
    # ? : evaluates one branch, a double if either branch is
    ("true ? 1 : 2.5", 0, 1.0, "double"),
    ("c > 0 ? 1 : 2.5", 0, 2.5, "double"),
    ("pow(true ? 2 : 0.5, -1)", 0, 0.5, "double"),
    ("c = 0 ? 0 : mod(5, c)", 0, 0, "int"),
    ("c = 0 ? mod(5, c) : 0", 0, ERROR, "int"),
    # & | => short-circuit; <=> does not
    ("c = 0 | pow(2, c - 1) > 0", 0, True, "bool"),
    ("c = 0 | pow(2, c - 1) > 0", 1, True, "bool"),
    ("c > 0 & pow(2, c - 1) >= 1", 0, False, "bool"),
    ("c > 0 => mod(5, c) >= 0", 0, True, "bool"),
    ("c != 0 & floor(1/c) >= 0", 0, False, "bool"),
    ("(c = 0) <=> (pow(2, c - 1) > 0)", 0, ERROR, "bool"),
    ("false => 1/0 > 0", 0, True, "bool"),
]


def _case_id(case: tuple[str, int, Any, ValueType]) -> str:
    return f"{case[0]} @c={case[1]}"


def _expr(text: str) -> Expr:
    return parse_property(text).formula


@pytest.mark.parametrize("case", CASES, ids=_case_id)
def test_prism_value_by_constant_evaluation(case: tuple[str, int, Any, ValueType]) -> None:
    text, c, expected, kind = case
    if expected == ERROR:
        with pytest.raises(EvaluationError):
            evaluate(_expr(text), {"c": c})
        return
    got = evaluate(_expr(text), {"c": c})
    assert {"int": int, "double": float, "bool": bool}[kind] is type(got)
    assert _same(expected, got, kind)


@pytest.mark.parametrize("case", CASES, ids=_case_id)
@pytest.mark.parametrize("tabulated", [False, True], ids=["rows", "table"])
def test_prism_value_in_the_builder(case: tuple[str, int, Any, ValueType],
                                    tabulated: bool) -> None:
    """Vectorised over c = 0..4 with the others, and in the case's state alone."""
    text, c, expected, kind = case
    ranges = {"c": (-1, 4)} if tabulated else None
    compiled = compile_expr(_expr(text), ("c",), ranges=ranges, cache=CompileCache())
    if expected == ERROR:
        with pytest.raises(ModelError):
            compiled(np.array([[c]], dtype=np.int64))
        return
    got = compiled(np.array([[c]], dtype=np.int64))
    assert got.dtype.kind == {"int": "i", "double": "f", "bool": "b"}[kind]
    assert _same(expected, got[0], kind)


#: Cases without an exact rational value, or whose double is not it.
NOT_RATIONAL = frozenset({
    "22/7", "c/0", "-c/0", "1/c > 100", "pow(9.0, 0.5)", "pow(-8, 0.5)", "pow(0.0, -1)",
    "pow(1.0, 0/0)", "min(1/0, 2)", "max(0/0, 1)", "1/min(0.0, -0.0)", "1/max(-0.0, 0.0)",
})


@pytest.mark.parametrize(
    "case", [c for c in CASES if c[0] not in NOT_RATIONAL and "log" not in c[0]], ids=_case_id)
def test_prism_value_in_exact_rationals(case: tuple[str, int, Any, ValueType]) -> None:
    """Where PRISM's value is a finite rational, --exact gives it exactly."""
    text, c, expected, kind = case
    column = _objects([mpq(c)])
    if expected == ERROR:
        with pytest.raises(ModelError):
            evaluate_rational(_expr(text), {}, {"c": column}, 1)
        return
    got = evaluate_rational(_expr(text), {}, {"c": column}, 1)[0]
    if kind == "bool":
        assert bool(got) == expected
    else:
        assert Fraction(int(got.numerator), int(got.denominator)) == Fraction(expected)


@pytest.mark.parametrize(
    ("text", "message"),
    [("c/0", "division by zero"), ("pow(0.0, -1)", "zero to a negative power"),
     ("log(8, 2)", "no exact rational value"), ("pow(9.0, 0.5)", "non-integer exponent")],
)
def test_no_exact_value_is_an_error_in_rationals(text: str, message: str) -> None:
    with pytest.raises(ModelError, match=message):
        evaluate_rational(_expr(text), {}, {"c": _objects([mpq(1)])}, 1)


def test_a_vectorised_guard_does_not_fail_where_prism_does_not_evaluate() -> None:
    """``c=0 | pow(2,c-1)>0`` over states with c=0: no negative exponent reported."""
    states = np.array([[0], [1], [2], [0]], dtype=np.int64)
    for ranges in (None, {"c": (0, 2)}):
        compiled = compile_expr(_expr("c=0 | pow(2,c-1)>0"), ("c",), ranges=ranges)
        assert compiled(states).tolist() == [True, True, True, True]
        compiled = compile_expr(_expr("c>0 ? pow(2,c-1) : -1"), ("c",), ranges=ranges)
        assert compiled(states).tolist() == [-1, 1, 2, -1]
