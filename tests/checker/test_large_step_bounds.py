"""Step bounds too large to iterate (``F<=10^15``): certified, decided in well under a
second, never a hang; and refused in exact arithmetic with the limit named.

GEO (the fuzzer's model): from x=0 half the mass moves to the absorbing x=1 each step,
so ``P(F<=k x=1) = 1 - 2^-k``. The float iteration sits at 1.0 after ~55 steps; its
radius used to be multiplied out over the 10^15 steps left (``1 ± inf``), and the
undecided bound then raised the rational matrix to the 10^15th power. TENTH's row
``0.9 + 0.1`` sums to ``1 + 2^-55`` as stored, so its step-bounded values approach
``L = 0.1 / (1 - 0.9) > 1`` (the doubles), above the unbounded until.
"""

from __future__ import annotations

import json
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from click.testing import CliRunner
from gmpy2 import mpz

from tests.checker import exact_reference as ref
from veribattery.checker import UndecidedResult, Workspace, kernels
from veribattery.checker.certify import horizon
from veribattery.checker.certify.bounds import Bounds, required_precision
from veribattery.cli import cli
from veribattery.errors import CheckError
from veribattery.pipeline import check_prism_file

GEO = """dtmc
module m
  x : [0..1] init 0;
  [] x=0 -> 0.5:(x'=0) + 0.5:(x'=1);
  [] x=1 -> (x'=1);
endmodule
rewards "r"
  x=0 : 1;
endrewards
rewards "steps"
  true : 1;
endrewards
"""
TENTH = GEO.replace("0.5:(x'=0) + 0.5:(x'=1)", "0.9:(x'=0) + 0.1:(x'=1)")
HUGE = 10**15
LARGEST = 2**63 - 1


@pytest.mark.parametrize(("prop", "holds"), [
    (f"P>=0.9 [ F<={HUGE} x=1 ]", True),
    (f"P<0.9 [ F<={HUGE} x=1 ]", False),
    (f"P<0.9 [ G<={HUGE} x=0 ]", True),
    (f"P>0.1 [ G<={HUGE} x=0 ]", False),
    (f"P>=0.9 [ F<={LARGEST} x=1 ]", True),
    (f"P>=0.9 [ x=0 U<={HUGE} x=1 ]", True),
    (f"P>=0.9 [ F[{HUGE},{HUGE + 5}] x=1 ]", True),  # x=1 holds from then on
])
def test_bounds_far_from_the_value_are_decided_at_once(prop: str, holds: bool) -> None:
    start = time.perf_counter()
    run = check_prism_file(GEO, selectors=(prop,))
    assert run.results[0].value is holds
    assert run.warnings == ()  # decided in floating point: no exact check
    assert time.perf_counter() - start < 30  # (0.05 s; it used to run forever)


@pytest.mark.parametrize("k", [HUGE, LARGEST])
def test_value_is_one_to_within_1e9(k: int) -> None:
    """The unbounded until (exactly 1: graph analysis) caps the interval, as the rows
    sum to 1 exactly; the lower bound is the iteration's at its float fixpoint."""
    result = check_prism_file(GEO, selectors=(f"P=? [ F<={k} x=1 ]",)).results[0]
    assert result.value == 1.0 and result.upper == 1.0
    assert result.lower is not None and 1 - 1e-14 < result.lower < 1.0
    assert result.precise


def test_globally_is_zero_to_within_1e9() -> None:
    result = check_prism_file(GEO, selectors=(f"P=? [ G<={HUGE} x=0 ]",)).results[0]
    assert result.value == 0.0 and result.lower == 0.0
    assert result.upper is not None and 0.0 < result.upper < 1e-14


@pytest.mark.parametrize("k", [HUGE, LARGEST])
def test_rows_summing_above_one_keep_their_own_limit(k: int) -> None:
    """No ceiling from the unbounded until here (it would be 1, below the stored
    chain's values): the radius alone is iterated to where it no longer grows."""
    result = check_prism_file(TENTH, selectors=(f"P=? [ F<={k} x=1 ]",)).results[0]
    limit = Fraction(0.1) / (1 - Fraction(0.9))
    assert limit > 1
    # x_k = L (1 - 0.9^k): below L by less than 2^-(10^14), far below any float's gap.
    assert result.lower is not None and result.upper is not None
    assert Fraction(result.lower) < limit <= Fraction(result.upper)
    assert result.upper - result.lower <= 1e-9 and result.precise


def test_cumulative_reward_that_settles() -> None:
    """``C<=k`` of a reward earned only in the transient state: 2 expected steps."""
    result = check_prism_file(GEO, selectors=(f'R{{"r"}}=? [ C<={HUGE} ]',)).results[0]
    assert result.value == 2.0 and result.precise
    assert result.lower is not None and result.upper is not None
    assert result.lower <= 2.0 <= result.upper and result.upper - result.lower < 1e-13


def test_cumulative_reward_that_grows_stops_with_a_lower_bound(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``C<=k`` of one per step grows without end: the rounds a large bound may run are
    run, and what is certified is the lower bound they reach (the reward never falls)."""
    monkeypatch.setattr(horizon, "BEYOND_ROUNDS", 2048)
    result = check_prism_file(GEO, selectors=(f'R{{"steps"}}=? [ C<={HUGE} ]',)).results[0]
    assert result.lower is not None and 2047.99 < result.lower <= 2048.0
    assert result.upper == np.inf and not result.precise


def test_a_step_bound_of_2_to_the_63_is_refused(tmp_path: Path) -> None:
    with pytest.raises(CheckError, match=r"step bound 9223372036854775808 is too large "
                                         r"\(at most 2\^63 - 1\)"):
        check_prism_file(GEO, selectors=(f"P=? [ F<={2**63} x=1 ]",))
    model, props = tmp_path / "geo.pm", tmp_path / "geo.props"
    model.write_text(GEO)
    props.write_text("const int K;\nP=? [ F<=K x=1 ];\n")
    result = CliRunner().invoke(cli, ["prism", str(model), "--props", str(props),
                                      "--const", f"K={2**63}"])
    assert result.exit_code == 2
    # (the constant itself is out of the int range: refused where it is given)
    assert result.stderr.strip() == (
        "error: constant 'K' (--const K=9223372036854775808): 9223372036854775808 is out of "
        "the int range -2^63..2^63-1 (ints are 64-bit here; PRISM's are 32-bit): use a "
        "smaller int, or a double such as 1e19")


# ---------------------------------------------------------------------------
# Exact arithmetic: a limit on the steps, named
# ---------------------------------------------------------------------------


def test_undecided_bound_stays_undecided_with_the_reason() -> None:
    """``1 - 2^-(10^15) >= 1`` is false, but only exact arithmetic could tell, and
    10^15 exact steps are out of reach: undecided, saying why, at once."""
    run = check_prism_file(GEO, selectors=(f"P>=1 [ F<={HUGE} x=1 ]",))
    result = run.results[0]
    assert isinstance(result, UndecidedResult)
    assert result.reason.endswith("not decidable in exact arithmetic: <property>:1:11: step "
                                  "bound 1000000000000000 is too large for exact arithmetic "
                                  "(at most 100,000 steps)")


def test_exact_mode_refuses_with_the_bound_and_the_limit(tmp_path: Path) -> None:
    model, props = tmp_path / "geo.pm", tmp_path / "geo.props"
    model.write_text(GEO)
    props.write_text(f"P=? [ F<=3 x=1 ];\nP=? [ G<=3 x=0 ];\nP=? [ F<={HUGE} x=1 ];\n"
                     f"R{{\"r\"}}=? [ C<=100001 ];\nP=? [ F[2,{HUGE}] x=1 ];\n")
    runner = CliRunner()
    for index, exact in ((1, "7/8"), (2, "1/8")):
        result = runner.invoke(cli, ["prism", str(model), "--props", str(props), "--exact",
                                     "--property", str(index), "--json"])
        assert result.exit_code == 0 and f'"exact": "{exact}"' in result.stdout
    for index, where, bound in ((3, "3:10", HUGE), (4, "4:15", 100001), (5, "5:11", HUGE)):
        result = runner.invoke(cli, ["prism", str(model), "--props", str(props), "--exact",
                                     "--property", str(index)])
        assert result.exit_code == 2
        assert result.stderr.strip() == (
            f"error: {props}:{where}: step bound {bound} is too large for exact arithmetic "
            "(at most 100,000 steps)")


# ---------------------------------------------------------------------------
# The kernel against exact values, with the limits made small
# ---------------------------------------------------------------------------


def _dyadic_chain(seed: int, n: int = 10) -> tuple[sp.csr_matrix, np.ndarray]:
    """Rows of 1/2, 1/4, ... (exactly stochastic), a self-loop on each, two targets and
    a trap (the last state): the unbounded until is a solve, strictly inside (0, 1)."""
    rng = np.random.default_rng(seed)
    dense = np.zeros((n, n))
    for state in range(n - 1):
        share = 1.0
        for successor in (state, *rng.choice(n, 2, replace=False)):
            share /= 2
            dense[state, successor] += share
        dense[state, state] += share
    dense[n - 1, n - 1] = 1.0
    target = np.zeros(n, dtype=bool)
    target[rng.choice(n - 1, 2, replace=False)] = True
    return sp.csr_matrix(dense), target


def _decimal_chain(seed: int, n: int = 10) -> tuple[sp.csr_matrix, np.ndarray]:
    """Rows normalised in floating point (some sum above 1), two targets."""
    rng = np.random.default_rng(seed)
    dense = (rng.random((n, n)) < 0.3) * rng.random((n, n))
    dense[np.arange(n), np.arange(n)] += 0.5
    dense /= dense.sum(axis=1, keepdims=True)
    target = np.zeros(n, dtype=bool)
    target[rng.choice(n, 2, replace=False)] = True
    return sp.csr_matrix(dense), target


def _exact(P: sp.csr_matrix, target: np.ndarray, k: int) -> list[Fraction]:
    moving = sp.csr_matrix(sp.diags((~target).astype(float)) @ P)
    hit = [Fraction(int(t)) for t in target]
    return ref.step_power(moving, hit, hit, k)


def _contains(found: Bounds, exact: list[Fraction]) -> bool:
    return all(Fraction(float(lo)) <= e and (hi == np.inf or e <= Fraction(float(hi)))
               for lo, e, hi in zip(found.lower, exact, found.upper, strict=True))


@pytest.fixture
def small_limits(monkeypatch: pytest.MonkeyPatch) -> None:
    """Bounds above 40 steps run at most 64 rounds, first checked after 16."""
    monkeypatch.setattr(horizon, "ROUND_LIMIT", 40)
    monkeypatch.setattr(horizon, "BEYOND_ROUNDS", 64)
    monkeypatch.setattr(horizon, "FIRST_CHECK", 16)


@pytest.mark.usefixtures("small_limits")
@pytest.mark.parametrize("chain", [_dyadic_chain, _decimal_chain])
@pytest.mark.parametrize("precision", [(1e-9, 1e-12), (1e-300, 1e-300)])
@pytest.mark.parametrize("seed", range(6))
def test_bounds_beyond_the_rounds_run_contain_the_exact_values(
        chain: object, precision: tuple[float, float], seed: int) -> None:
    """``U<=300`` from 64 rounds at most: the enclosure of the steps not run (the
    unbounded until above, the last lower bound below, or the radius carried over
    from a float fixpoint) holds the exact 300-step values of the stored chain."""
    assert callable(chain)
    P, target = chain(seed)
    everywhere = np.ones(len(target), dtype=bool)
    with required_precision(*precision):
        found = kernels.bounded_until_probs(P, everywhere, target, 300,
                                            workspace=Workspace())
    assert _contains(found, _exact(P, target, 300))


@pytest.mark.parametrize("seed", range(4))
def test_imprecise_radius_is_carried_on_alone(seed: int) -> None:
    """At a float fixpoint whose normwise radius over the steps left is not precise,
    the radius is iterated on alone: still the exact values, and narrower."""
    P, target = _dyadic_chain(seed)
    everywhere = np.ones(len(target), dtype=bool)
    with required_precision(1e-300, 1e-300):
        found = kernels.bounded_until_probs(P, everywhere, target, 400)
    assert _contains(found, _exact(P, target, 400))
    assert float(np.max(found.width)) < 1e-12


def test_exact_results_of_more_than_4300_digits_print(tmp_path: Path) -> None:
    """10^4 exact steps with thirds: P(F<=k x>0) = 1 - (1/3)^k has a 4,772-digit
    denominator, past Python's guard on int -> str (a ValueError traceback before)."""
    model = tmp_path / "thirds.pm"
    model.write_text("dtmc\nmodule m\n  x : [0..2] init 0;\n"
                     "  [] x=0 -> 1/3:(x'=0) + 1/3:(x'=1) + 1/3:(x'=2);\n"
                     "  [] x>0 -> (x'=2);\nendmodule\n")
    runner = CliRunner()
    args = ["prism", str(model), "--exact", "--property", "P=? [ F<=2 x>0 ]",
            "--property", "P=? [ F<=10000 x>0 ]"]
    table = runner.invoke(cli, args)
    assert table.exit_code == 0
    assert "8/9 ≈ 0.888888888889" in table.stdout and "(p/q: 4772/4772 digits)" in table.stdout
    result = runner.invoke(cli, [*args, "--json"])
    assert result.exit_code == 0
    power = mpz(3) ** 10000  # (gmpy2 prints it: Python's int would refuse too)
    assert json.loads(result.stdout)["results"][1]["exact"] == f"{power - 1}/{power}"


#: Two states swapping with 1/4 each step; a reward of 1 in the first: the expected
#: reward of k steps from it is k/2 + 1 - 2^-k (the chance of being there after i steps
#: is 1/2 + 2^-(i+1)).
SWAP = """dtmc
module m
  s : [0..1] init 0;
  [] s=0 -> 0.25:(s'=1) + 0.75:(s'=0);
  [] s=1 -> 0.25:(s'=0) + 0.75:(s'=1);
endmodule
rewards "r"
  s=0 : 1;
endrewards
"""


@pytest.mark.parametrize("k", [3000, 10**6])
def test_cumulative_reward_is_carried_by_its_gain(k: int, gains_carried: list[int]) -> None:
    """Once the steps' increments are the same in both states (the gain 1/2), the rounds
    left are carried forward (``horizon.gained``): 10^6 rounds took a minute."""
    result = check_prism_file(SWAP, selectors=(f'R=? [ C<={k} ]',)).results[0]
    exact = Fraction(k, 2) + 1 - Fraction(1, 2**k)
    assert result.precise and result.lower is not None and result.upper is not None
    assert Fraction(result.lower) <= exact <= Fraction(result.upper)
    assert gains_carried and gains_carried[-1] > k // 3  # (a third of the rounds left, or more)


def test_carried_bounds_meet_the_rounds_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """The same bound carried and with every round run: overlapping intervals, the same
    value to 1e-12; and a reward whose increments differ between two absorbing states
    (no single gain) runs every round."""
    text = SWAP.replace("  s=0 : 1;", "  s=0 : 1;\n  s=1 : 0.3;")
    carried = check_prism_file(text, selectors=("R=? [ C<=50000 ]",)).results[0]
    monkeypatch.setattr(horizon, "gain_checkpoint", lambda done, k: False)
    run = check_prism_file(text, selectors=("R=? [ C<=50000 ]",)).results[0]
    assert carried.lower <= run.upper and run.lower <= carried.upper  # type: ignore[operator]
    assert float(carried.value) == pytest.approx(float(run.value), rel=1e-12)
    monkeypatch.undo()
    result = check_prism_file(TWO_WAYS, selectors=("R=? [ C<=5000 ]",)).results[0]
    assert result.lower <= 2499.5 <= result.upper and result.precise  # type: ignore[operator]


#: From x=2 to one of two absorbing states, one earning 1 a step: 2499.5 in 5000 steps.
TWO_WAYS = """dtmc
module m
  x : [0..2] init 2;
  [] x=2 -> 0.5:(x'=0) + 0.5:(x'=1);
  [] x<2 -> true;
endmodule
rewards "r"
  x=0 : 1;
endrewards
"""
