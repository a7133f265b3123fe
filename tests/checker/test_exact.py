"""``--exact``: rational results checked against values derived independently.

The oracles here share nothing with the implementation: hand-solved chains,
and for random chains a dense Gauss-Jordan over :class:`fractions.Fraction`
on the whole state space (qualitative pre-pass by a plain graph search) and
step-bounded operators by repeated Fraction matrix-vector products.
"""

from __future__ import annotations

import json
import math
import random
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.checker.exact import ExactCheckResult
from veribattery.checker.exact import solve as exact_solve
from veribattery.cli import cli
from veribattery.errors import ModelError
from veribattery.pipeline import check_prism_file

#: The chain built to defeat floating-point solvers (one copy, shared with bench/).
HADDAD_MONMEGE = (Path(__file__).parents[1] / "data" / "haddad_monmege.prism").read_text()


def exact_run(model: str, *properties: str, **constants: str) -> list[ExactCheckResult]:
    run = check_prism_file(model, selectors=properties, constants=constants, exact=True)
    results = [r for r in run.results if isinstance(r, ExactCheckResult)]
    assert len(results) == len(properties)
    return results


@pytest.mark.parametrize("n", [20, 100, 300])
def test_haddad_monmege_is_seven_tenths(n: int) -> None:
    """Floating-point solvers print ~1e-14 or 0.5 here; the exact answer is 7/10 for every N."""
    value, geq, gt = exact_run(
        HADDAD_MONMEGE, "P=? [ F x=0 ]", "P>=0.7 [ F x=0 ]", "P>0.7 [ F x=0 ]", N=str(n), p="0.7"
    )
    assert value.exact == Fraction(7, 10)
    assert value.value == 0.7
    assert (geq.value, gt.value) == (True, False)  # decided exactly, at the boundary


def test_haddad_monmege_through_the_sparse_eliminator(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every component through the one-by-one elimination path gives the same 7/10."""
    monkeypatch.setattr(exact_solve, "BATCH_LIMIT", 0)
    (value,) = exact_run(HADDAD_MONMEGE, "P=? [ F x=0 ]", N="20", p="0.7")
    assert value.exact == Fraction(7, 10)


KNUTH_DIE = """dtmc
module die
  s : [0..7] init 0;
  d : [0..6] init 0;
  [] s=0 -> 0.5 : (s'=1) + 0.5 : (s'=2);
  [] s=1 -> 0.5 : (s'=3) + 0.5 : (s'=4);
  [] s=2 -> 0.5 : (s'=5) + 0.5 : (s'=6);
  [] s=3 -> 0.5 : (s'=1) + 0.5 : (s'=7) & (d'=1);
  [] s=4 -> 0.5 : (s'=7) & (d'=2) + 0.5 : (s'=7) & (d'=3);
  [] s=5 -> 0.5 : (s'=7) & (d'=4) + 0.5 : (s'=7) & (d'=5);
  [] s=6 -> 0.5 : (s'=2) + 0.5 : (s'=7) & (d'=6);
  [] s=7 -> (s'=7);
endmodule
rewards "coin"
  s<7 : 1;
endrewards
"""


def test_knuth_die_faces_and_expected_flips() -> None:
    faces = [f"P=? [ F s=7 & d={k} ]" for k in range(1, 7)]
    results = exact_run(KNUTH_DIE, *faces, 'R{"coin"}=? [ F s=7 ]', "P=? [ F<=3 s=7 ]")
    assert [r.exact for r in results[:6]] == [Fraction(1, 6)] * 6
    assert results[6].exact == Fraction(11, 3)
    assert results[7].exact == Fraction(3, 4)  # 4 of the 8 three-flip paths end by step 3


def test_decimal_literals_and_constants_are_exact() -> None:
    """0.1 is 1/10 (not the double 0.1000000000000000055...), 1/3 stays 1/3."""
    model = """dtmc
const double third = 1/3;
const double r;
module m
  s : [0..4] init 0;
  [] s<3 -> 0.1:(s'=s+1) + 0.9:(s'=4);
  [] s=3 -> third:(s'=3) + (1-third):(s'=4);
  [] s=4 -> true;
endmodule
rewards
  s=3 : r;
endrewards
"""
    reach, step, reward = exact_run(
        model, "P=? [ F s=3 ]", "P=? [ X s=1 ]", "R=? [ F s=4 ]", r="0.7"
    )
    assert reach.exact == Fraction(1, 1000)
    assert step.exact == Fraction(1, 10)
    # reach s=3 w.p. 1/1000, then earn 7/10 per step for 1/(1-1/3) = 3/2 expected steps
    assert reward.exact == Fraction(1, 1000) * Fraction(7, 10) * Fraction(3, 2)


def test_infinite_reward_and_globally_and_lower_bounds() -> None:
    model = """dtmc
module m
  s : [0..3] init 0;
  [] s=0 -> 1/4:(s'=1) + 3/4:(s'=2);
  [] s=1 -> 1/2:(s'=1) + 1/2:(s'=3);
  [] s>=2 -> true;
endmodule
rewards
  true : 1;
endrewards
"""
    infinite, sure, always, later, bounded_reward = exact_run(
        model, "R=? [ F s=3 ]", "R=? [ F s>=2 ]", "P=? [ G s!=3 ]", "P=? [ F>=2 s=3 ]",
        "R>=1 [ F s=3 ]",
    )
    assert math.isinf(infinite.value) and infinite.exact is None
    assert sure.exact == Fraction(1) + Fraction(1, 4) * 2  # one step, then 2 expected in s=1
    assert always.exact == Fraction(3, 4)
    assert later.exact == Fraction(1, 4)  # s=3 is first hit at step 2 or later
    assert bounded_reward.value is True  # infinity exceeds every bound


def test_nondeterminism_is_uniform_and_exact() -> None:
    model = """dtmc
module m
  s : [0..2] init 0;
  [] s=0 -> 1/3:(s'=1) + 2/3:(s'=2);
  [] s=0 -> (s'=1);
  [] s>0 -> true;
endmodule
"""
    (value,) = exact_run(model, "P=? [ X s=1 ]")
    assert value.exact == Fraction(1, 2) * Fraction(1, 3) + Fraction(1, 2)


# ---------------------------------------------------------------------------
# Random chains against a Fraction oracle
# ---------------------------------------------------------------------------


def random_chain(seed: int, n: int) -> list[dict[int, Fraction]]:
    """Rows of a random DTMC with small-denominator probabilities and some absorbing states."""
    rng = random.Random(seed)
    rows: list[dict[int, Fraction]] = []
    for s in range(n):
        if rng.random() < 0.2:
            rows.append({s: Fraction(1)})
            continue
        targets = rng.sample(range(n), rng.randint(1, min(4, n)))
        weights = [rng.randint(1, 9) for _ in targets]
        total = sum(weights)
        row: dict[int, Fraction] = {}
        for t, w in zip(targets, weights, strict=True):
            row[t] = row.get(t, Fraction(0)) + Fraction(w, total)
        rows.append(row)
    return rows


def chain_text(rows: Sequence[dict[int, Fraction]]) -> str:
    commands = []
    for s, row in enumerate(rows):
        branches = " + ".join(f"{p.numerator}/{p.denominator}:(s'={t})" for t, p in row.items())
        commands.append(f"  [] s={s} -> {branches};")
    body = "\n".join(commands)
    return f"dtmc\nmodule m\n  s : [0..{len(rows) - 1}] init 0;\n{body}\nendmodule\n" \
           f"rewards\n  true : 1/2;\n  s=1 : 3;\nendrewards\n"


def reachable_to(rows: Sequence[dict[int, Fraction]], target: set[int]) -> set[int]:
    found = set(target)
    changed = True
    while changed:
        changed = False
        for s, row in enumerate(rows):
            if s not in found and any(t in found for t in row):
                found.add(s)
                changed = True
    return found


def fraction_solve(matrix: list[list[Fraction]], rhs: list[Fraction]) -> list[Fraction]:
    """Gauss-Jordan with partial pivoting over Fractions."""
    n = len(rhs)
    a = [[*row, b] for row, b in zip(matrix, rhs, strict=True)]
    for i in range(n):
        pivot = next(r for r in range(i, n) if a[r][i] != 0)
        a[i], a[pivot] = a[pivot], a[i]
        a[i] = [v / a[i][i] for v in a[i]]
        for r in range(n):
            if r != i and a[r][i] != 0:
                factor = a[r][i]
                a[r] = [v - factor * w for v, w in zip(a[r], a[i], strict=True)]
    return [a[i][n] for i in range(n)]


def oracle_reach(rows: Sequence[dict[int, Fraction]], target: set[int]) -> list[Fraction]:
    """P(F target) per state: 0 where target is unreachable, else the linear system."""
    can = reachable_to(rows, target)
    unknown = [s for s in range(len(rows)) if s in can and s not in target]
    index = {s: i for i, s in enumerate(unknown)}
    matrix = [[Fraction(int(i == j)) for j in range(len(unknown))] for i in range(len(unknown))]
    rhs = [Fraction(0)] * len(unknown)
    for s in unknown:
        for t, p in rows[s].items():
            if t in index:
                matrix[index[s]][index[t]] -= p
            elif t in target:
                rhs[index[s]] += p
    solution = fraction_solve(matrix, rhs)
    return [Fraction(1) if s in target else solution[index[s]] if s in index else Fraction(0)
            for s in range(len(rows))]


def oracle_reward(rows: Sequence[dict[int, Fraction]], target: set[int],
                  reward: list[Fraction]) -> list[Fraction | None]:
    """R(F target) per state, None for infinity (target not almost sure)."""
    reach = oracle_reach(rows, target)
    sure = [s for s in range(len(rows)) if reach[s] == 1 and s not in target]
    index = {s: i for i, s in enumerate(sure)}
    matrix = [[Fraction(int(i == j)) for j in range(len(sure))] for i in range(len(sure))]
    for s in sure:
        for t, p in rows[s].items():
            if t in index:
                matrix[index[s]][index[t]] -= p
    solution = fraction_solve(matrix, [reward[s] for s in sure])
    return [Fraction(0) if s in target else solution[index[s]] if s in index else None
            for s in range(len(rows))]


def oracle_step(rows: Sequence[dict[int, Fraction]], x: list[Fraction]) -> list[Fraction]:
    return [sum((p * x[t] for t, p in row.items()), Fraction(0)) for row in rows]


@pytest.mark.parametrize("seed", range(12))
def test_random_chains_match_the_fraction_oracle(seed: int) -> None:
    rows = random_chain(seed, 9)
    target = {len(rows) - 1, len(rows) - 2}
    text = chain_text(rows)
    reward = [Fraction(1, 2) + (3 if s == 1 else 0) for s in range(len(rows))]
    reach, rew, bounded, cumulative, instant = exact_run(
        text, "P=? [ F s>=7 ]", "R=? [ F s>=7 ]", "P=? [ F<=4 s>=7 ]", "R=? [ C<=3 ]",
        "R=? [ I=2 ]",
    )
    assert reach.exact == oracle_reach(rows, target)[0]
    expected = oracle_reward(rows, target, reward)[0]
    assert rew.exact == expected and (expected is not None or math.isinf(rew.value))
    hit = [Fraction(int(s in target)) for s in range(len(rows))]
    x = hit
    for _ in range(4):
        x = [hit[s] or step for s, step in enumerate(oracle_step(rows, x))]
    assert bounded.exact == x[0]
    c = [Fraction(0)] * len(rows)
    for _ in range(3):
        c = [r + v for r, v in zip(reward, oracle_step(rows, c), strict=True)]
    assert cumulative.exact == c[0]
    state_reward = [Fraction(1, 2) + (3 if s == 1 else 0) for s in range(len(rows))]
    assert instant.exact == oracle_step(rows, oracle_step(rows, state_reward))[0]


# ---------------------------------------------------------------------------
# Bad input and the CLI
# ---------------------------------------------------------------------------

NO_RATIONAL = {
    "log": "[] s=0 -> log(4, 2)/4:(s'=1) + 1/2:(s'=0);",
    "pow": "[] s=0 -> pow(0.25, 0.5):(s'=1) + 1/2:(s'=0);",
}


@pytest.mark.parametrize("name", sorted(NO_RATIONAL))
def test_expression_without_exact_value_is_one_line_exit_2(name: str, tmp_path) -> None:
    path = tmp_path / "m.pm"
    path.write_text(f"dtmc\nmodule m\n  s : [0..1] init 0;\n  {NO_RATIONAL[name]}\n"
                    "  [] s=1 -> true;\nendmodule\n")
    result = CliRunner().invoke(cli, ["prism", str(path), "--property", "P=? [ F s=1 ]",
                                      "--exact"])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{path}:4:" in lines[0] and name in lines[0], lines
    assert "no exact rational value" in lines[0]
    assert result.stdout == ""


def test_probabilities_must_sum_to_exactly_one() -> None:
    model = "dtmc\nmodule m\n s:[0..1] init 0;\n [] s=0 -> 0.3333333:(s'=0) + 0.6666666:(s'=1);" \
            "\n [] s=1 -> true;\nendmodule\n"
    assert check_prism_file(model, selectors=["P=? [ F s=1 ]"]).results[0].value == 1.0
    with pytest.raises(ModelError, match="sum to 9999999/10000000, not 1"):
        check_prism_file(model, selectors=["P=? [ F s=1 ]"], exact=True)


def test_cli_prints_the_fraction_and_json_carries_it(tmp_path) -> None:
    path = tmp_path / "hm.pm"
    path.write_text(HADDAD_MONMEGE)
    args = ["prism", str(path), "--property", "P=? [ F x=0 ]", "--property", "P>=0.7 [ F x=0 ]",
            "--const", "N=100,p=0.7", "--exact"]
    table = CliRunner().invoke(cli, args)
    assert table.exit_code == 0 and "7/10 ≈ 0.7" in table.stdout
    document = json.loads(CliRunner().invoke(cli, [*args, "--json"]).stdout)
    first, second = document["results"]
    assert (first["value"], first["exact"]) == (0.7, "7/10")
    assert second == {"property": "P>=0.7 [ F x=0 ]", "value": True}


def test_bounds_are_exact_as_written() -> None:
    """``P<=1/3`` holds at exactly 1/3 (the double nearest 1/3 is below it)."""
    model = "dtmc\nmodule m\n s:[0..2] init 0;\n [] s=0 -> 1/3:(s'=1) + 2/3:(s'=2);" \
            "\n [] s>0 -> true;\nendmodule\n"
    props = "const double third = 1/3;\nP<=1/3 [ F s=1 ];\nP>=third [ F s=1 ];\n" \
            "P<0.3333333333333333 [ F s=1 ];\n"
    run = check_prism_file(model, props_source=props, exact=True)
    assert [r.value for r in run.results] == [True, True, False]


def test_check_exact_cli_json_csv_and_exact_requirements() -> None:
    """``check --exact``: JSON gains ``exact``, CSV an ``exact`` column; requirements exact."""
    small = ["--set", "farm.cols=3", "--set", "farm.rows=2", "--set", "farm.base=[0,0]",
             "--set", "battery.capacity_ah=6", "--exact"]
    base = ["check", "configs/example.yaml", *small]
    document = json.loads(CliRunner().invoke(cli, [*base, "--format", "json"]).stdout)
    success = Fraction(document["exact"]["p_success"])
    assert float(success) == document["results"]["p_success"] and 0 < success < 1
    csv = CliRunner().invoke(cli, [*base, "--format", "csv"]).stdout.splitlines()
    assert csv[0] == "property,value,exact" and csv[1].endswith(f",{success}")
    # The exact value as the bound: >= holds, > fails (no rounding either way).
    for op, code in ((">=", 0), (">", 1)):
        requirement = f'requirements=["p_success {op} {success}"]'
        result = CliRunner().invoke(cli, [*base, "--set", requirement])
        assert result.exit_code == code, result.output
