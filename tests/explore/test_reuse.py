"""Structure reuse: re-evaluating probabilities on a known state space equals a fresh build.

Each re-evaluated DTMC is compared with a fresh build of the same model (states,
matrix entries, rewards, labels: identical), and values with hand-solved answers
in exact rational arithmetic. Fallbacks: a constant that reaches a guard, an
assignment or a range changes the key; a probability that becomes 0 or 1 (or
stops being 0) changes the branches; a model error at the new constants.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from veribattery.checker import check
from veribattery.errors import ModelError
from veribattery.explore import DTMC, build_dtmc
from veribattery.explore.reuse import structure as reuse
from veribattery.explore.reuse.structure import build_reusable, reevaluate, structure_key
from veribattery.lang import flatten_model, parse_model, parse_property
from veribattery.lang.nodes import FlatModel, Value
from veribattery.pipeline import ReusingBuilder

# Gambler's ruin on 0..N from 2, with a reward that depends on p too.
GAMBLER = """dtmc
const double p;
const int N;
module g
  x : [0..N] init 2;
  [step] x>0 & x<N -> p : (x'=x+1) + 1-p : (x'=x-1);
endmodule
label "win" = x=N;
rewards "cost"
  [step] true : 10*p;
  x=1 : p;
endrewards
"""

# Two modules synchronised on [t] with probabilistic updates in both, an
# unlabelled command (several enabled choices in some states), and deadlocks.
PRODUCT = """dtmc
const double p;
const double q;
const int T;
module a
  x : [0..3] init 0;
  [t] x<T -> p : (x'=x+1) + 1-p : true;
  [t] x=T -> true;
endmodule
module b
  y : [0..2] init 0;
  [t] true -> q*p : (y'=min(y+1,2)) + 1-q*p : (y'=0);
  [] y=2 -> 1 : (y'=0);
endmodule
label "top" = x=3 & y=2;
"""

# An init block: every state with x+y=1 is initial.
INIT_BLOCK = """dtmc
const double p;
module m
  x : [0..4];
  y : [0..1];
  [] x<4 -> p : (x'=x+1) + 1-p : (y'=1-y);
  [] x=4 -> true;
endmodule
init x+y=1 endinit
"""


#: Values of the models' other constants unless a test gives them.
DEFAULTS: dict[str, Value] = {"N": 6, "q": 0.5, "T": 3}


def flat(text: str, **constants: Value) -> FlatModel:
    return flatten_model(parse_model(text), {**DEFAULTS, **constants})


def assert_same_dtmc(got: DTMC, expected: DTMC) -> None:
    """Bit-identical: same numbering, matrix entries, rewards, labels and counts."""
    assert np.array_equal(got.states, expected.states)
    assert np.array_equal(got.initial, expected.initial)
    for name in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(got.transitions, name), getattr(expected.transitions, name))
    assert got.labels.keys() == expected.labels.keys()
    for label, mask in expected.labels.items():
        assert np.array_equal(got.labels[label], mask), label
    for ours, theirs in zip(got.rewards, expected.rewards, strict=True):
        assert np.array_equal(ours.state, theirs.state)
        assert np.array_equal(ours.transition, theirs.transition)
    assert (got.deadlocks, got.nondeterministic) == (expected.deadlocks, expected.nondeterministic)


def ruin(p: Fraction, start: int = 2, n: int = 6) -> Fraction:
    """P(reach n before 0 from *start*), the gambler's ruin in exact arithmetic."""
    if p == Fraction(1, 2):
        return Fraction(start, n)
    r = (1 - p) / p
    return (1 - r**start) / (1 - r**n)


@pytest.mark.parametrize("p", ["0.1", "0.45", "0.5", "0.8", "0.999999"])
def test_gambler_reused_equals_fresh_build_and_exact_value(p: str) -> None:
    base, structure = build_reusable(flat(GAMBLER, p=0.3))
    model = flat(GAMBLER, p=float(p))
    got = reevaluate(base, structure, model)
    assert got is not None
    assert_same_dtmc(got, build_dtmc(model))
    value = check(got, parse_property('P=? [ F "win" ]')).value
    assert value == pytest.approx(float(ruin(Fraction(p))), rel=1e-12)
    assert got.rewards[0].transition[1] == pytest.approx(10 * float(p), rel=1e-15)


@pytest.mark.parametrize("p", [0.05, 0.3, 0.77])
def test_synchronised_product_reused_equals_fresh_build(p: float) -> None:
    base, structure = build_reusable(flat(PRODUCT, p=0.6))
    model = flat(PRODUCT, p=p)
    got = reevaluate(base, structure, model)
    assert got is not None
    expected = build_dtmc(model)
    assert_same_dtmc(got, expected)
    assert got.nondeterministic > 0
    prop = parse_property('P=? [ F<=5 "top" ]')
    assert check(got, prop).value == pytest.approx(check(expected, prop).value, rel=1e-12)


def test_init_block_reused_equals_fresh_build() -> None:
    base, structure = build_reusable(flat(INIT_BLOCK, p=0.5))
    assert base.initial.size == 2
    model = flat(INIT_BLOCK, p=0.25)
    got = reevaluate(base, structure, model)
    assert got is not None
    assert_same_dtmc(got, build_dtmc(model))


def test_key_ignores_probability_constants_only() -> None:
    key = structure_key(flat(PRODUCT, p=0.6))
    assert structure_key(flat(PRODUCT, p=0.1)) == key
    assert structure_key(flat(PRODUCT, p=0.6, q=0.25)) == key
    assert structure_key(flat(PRODUCT, p=0.6, T=2)) != key  # T reaches a guard


def test_constant_in_guard_falls_back() -> None:
    base, structure = build_reusable(flat(PRODUCT, p=0.6))
    assert reevaluate(base, structure, flat(PRODUCT, p=0.6, T=2)) is None


def test_constant_in_range_or_assignment_falls_back() -> None:
    base, structure = build_reusable(flat(GAMBLER, p=0.3))
    assert reevaluate(base, structure, flat(GAMBLER, p=0.3, N=7)) is None
    shifted = GAMBLER.replace("(x'=x+1)", "(x'=min(x+K, N))").replace(
        "const int N;", "const int N;\nconst int K;"
    )
    base, structure = build_reusable(flat(shifted, p=0.3, K=1))
    assert reevaluate(base, structure, flat(shifted, p=0.3, K=1)) is not None
    assert reevaluate(base, structure, flat(shifted, p=0.3, K=2)) is None


@pytest.mark.parametrize("p", [0.0, 1.0])
def test_probability_becoming_zero_or_one_falls_back(p: float) -> None:
    base, structure = build_reusable(flat(PRODUCT, p=0.6))
    model = flat(PRODUCT, p=p)
    assert reevaluate(base, structure, model) is None
    assert build_dtmc(model).num_transitions < base.num_transitions


def test_probability_leaving_zero_falls_back() -> None:
    base, structure = build_reusable(flat(PRODUCT, p=0.0))
    assert base.num_states == 1  # neither x nor y ever moves
    model = flat(PRODUCT, p=0.5)
    assert reevaluate(base, structure, model) is None
    assert build_dtmc(model).num_states == 12


def test_zero_probability_branches_stay_dropped_when_reused() -> None:
    # 1-q*p is never 0 here, but with p=0 the [t] branch (x'=x+1) is: reused
    # between two points where the same branches are 0.
    base, structure = build_reusable(flat(PRODUCT, p=0.0, q=0.5))
    other = flat(PRODUCT, p=0.0, q=0.25)
    got = reevaluate(base, structure, other)
    assert got is not None
    assert_same_dtmc(got, build_dtmc(other))


def test_model_error_at_new_constants_falls_back() -> None:
    text = GAMBLER.replace("1-p : (x'=x-1)", "0.5 : (x'=x-1)")
    base, structure = build_reusable(flat(text, p=0.5))
    model = flat(text, p=0.6)
    assert reevaluate(base, structure, model) is None
    with pytest.raises(ModelError, match="sum to"):
        build_dtmc(model)


def test_reusing_builder_reports_which_way_each_model_ran() -> None:
    builder = ReusingBuilder()
    ways = []
    for p, n in [(0.3, 6), (0.4, 6), (0.0, 6), (0.5, 6), (0.5, 7), (0.2, 7)]:
        model = flat(GAMBLER, p=p, N=n)
        dtmc, reused = builder.build(model)
        assert_same_dtmc(dtmc, build_dtmc(model))
        ways.append(reused)
    # p=0 drops branches: built in full; it becomes the base, so p=0.5 is built again.
    assert ways == [False, True, False, False, False, True]


# --- the re-pricing way (branch kinds of the fused plan) ---------------------------

# A probability that depends on the state as well as on p (no division: not risky).
STATEFUL = GAMBLER.replace("p : (x'=x+1) + 1-p : (x'=x-1)",
                           "(x>2 ? p : p*p) : (x'=x+1) + (x>2 ? 1-p : 1-p*p) : (x'=x-1)")


@pytest.mark.parametrize("text", [GAMBLER, PRODUCT, INIT_BLOCK, STATEFUL])
def test_repricing_equals_fresh_build_without_expanding(
        text: str, monkeypatch: pytest.MonkeyPatch) -> None:
    base, structure = build_reusable(flat(text, p=0.3))
    assert structure.kinds is not None  # recorded, and checked against the build

    def no_expansion(*args: object) -> None:
        raise AssertionError("expanded the states again")

    monkeypatch.setattr(reuse, "_relayers", no_expansion)
    for p in (0.1, 0.65):
        model = flat(text, p=p)
        got = reevaluate(base, structure, model)
        assert got is not None
        assert_same_dtmc(got, build_dtmc(model))


def test_stateful_probability_value_is_exact() -> None:
    base, structure = build_reusable(flat(STATEFUL, p=0.5))
    got = reevaluate(base, structure, flat(STATEFUL, p=0.25))
    assert got is not None
    # From 2 the step up has probability 1/16, from 3..5 it is 1/4: solve exactly.
    value = check(got, parse_property('P=? [ F "win" ]'))
    x = _stateful_exact(Fraction(1, 4))
    assert value.lower is not None and value.upper is not None
    assert Fraction(value.lower) <= x <= Fraction(value.upper)


def _stateful_exact(p: Fraction) -> Fraction:
    """P(reach 6 before 0 from 2) with up-probability p*p below 3 and p from 3 on."""
    from tests.checker.exact_reference import solve

    up = {x: (p if x > 2 else p * p) for x in range(1, 6)}
    matrix = [[Fraction(int(i == j)) for j in range(5)] for i in range(5)]
    rhs = [Fraction(0)] * 5
    for x in range(1, 6):
        i = x - 1
        if x + 1 < 6:
            matrix[i][x] -= up[x]
        else:
            rhs[i] += up[x]
        if x - 1 > 0:
            matrix[i][x - 2] -= 1 - up[x]
    return solve(matrix, rhs)[1]


def test_risky_probability_takes_the_expansion_way(monkeypatch: pytest.MonkeyPatch) -> None:
    # A mod by a state expression has no value on some states (mod(x, x) at x=0, where
    # the command is disabled): re-pricing would need the guards to know where it is
    # evaluated, so the states are expanded again. (One that cannot fail within the
    # ranges, such as mod(x, x+1), is tabulated and re-priced like any other factor;
    # so is p/x, infinite at x=0, as in PRISM.)
    text = GAMBLER.replace("p : (x'=x+1) + 1-p : (x'=x-1)",
                           "p*(1+mod(x,x)) : (x'=x+1) + 1-p*(1+mod(x,x)) : (x'=x-1)")
    base, structure = build_reusable(flat(text, p=0.3))
    calls = []
    original = reuse._relayers

    def counted(*args: object) -> object:
        calls.append(1)
        return original(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(reuse, "_relayers", counted)
    model = flat(text, p=0.6)
    got = reevaluate(base, structure, model)
    assert got is not None and calls == [1]
    assert_same_dtmc(got, build_dtmc(model))


def test_reused_matrix_shares_the_base_index_arrays() -> None:
    # The checker's pattern memos then know the pattern by the arrays' identity
    # (linalg.index_digest); the matrix stays the fresh build's, entry for entry.
    base, structure = build_reusable(flat(GAMBLER, p=0.3))
    model = flat(GAMBLER, p=0.6)
    got = reevaluate(base, structure, model)
    assert got is not None
    assert got.transitions.indices is base.transitions.indices
    assert got.transitions.indptr is base.transitions.indptr
    assert_same_dtmc(got, build_dtmc(model))
    value = check(got, parse_property('P=? [ F "win" ]')).value
    assert value == pytest.approx(float(ruin(Fraction("0.6"))), rel=1e-12)
