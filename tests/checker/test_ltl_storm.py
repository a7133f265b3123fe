"""LTL against Storm on random models and random formulas.

Random DTMCs and MDPs (dyadic probabilities, so the float model is the exact one) and
random LTL formulas over their labels; Storm's *exact* engine gives the value at the
initial state, which must lie inside veribattery's certified interval, the point value
agreeing to 1e-9. ``Pmin`` goes through the complemented automaton and ``Pmax`` through
the automaton itself, so both directions of every formula are compared.
"""

from __future__ import annotations

import random
from fractions import Fraction
from pathlib import Path

import pytest

stormpy = pytest.importorskip("stormpy")

from tests.checker.mdp.storm_mdp import DYADIC, GENERAL, random_model  # noqa: E402
from veribattery import check_prism_file  # noqa: E402

ATOMS = ('"goal"', '"safe"', "x0=1", "x0<1")


def random_formula(rng: random.Random, depth: int, *, top: bool = True) -> str:
    """An LTL formula over :data:`ATOMS`, with X F G U ! & | (what Storm's parser takes),
    an operator at the top."""
    if depth == 0 or (not top and rng.random() < 0.2):
        return rng.choice(ATOMS)
    # (weighted towards the operators that read a path's first steps: over a random
    # chain G F and F G are mostly 0 or 1)
    kind = rng.choice(["X"] * 3 + ["U"] * 3 + ["F", "G", "&", "|"] * 2 + ["!", "GF", "FG"])
    sub = lambda: random_formula(rng, depth - 1, top=False)  # noqa: E731
    if kind in ("X", "F", "G", "!"):
        return f"{kind} ({sub()})"
    if kind in ("GF", "FG"):
        return f"{kind[0]} {kind[1]} ({sub()})"
    return f"({sub()}) {kind} ({sub()})"


def random_model_text(rng: random.Random, kind: str, *, dyadic: bool = True) -> str:
    """A small random DTMC or MDP over x0 (an MDP: one or two choices per value; a few
    values absorbing, so that paths split between end components), labels "goal" and
    "safe"."""
    top = rng.randint(3, 7)
    lines = [kind, "", "module m0", f"  x0 : [0..{top}] init 0;"]
    for value in range(top + 1):
        if value > 0 and rng.random() < 0.4:
            lines.append(f"  [] x0={value} -> true;")
            continue
        for _ in range(1 if kind == "dtmc" else rng.randint(1, 2)):
            weights = rng.choice(DYADIC[1:] if dyadic else GENERAL)
            branches = " + ".join(f"{Fraction(w, sum(weights))}:(x0'={rng.randint(0, top)})"
                                  for w in weights)
            lines.append(f"  [] x0={value} -> {branches};")
    goal = " | ".join(f"x0={v}" for v in rng.sample(range(top + 1), 3))
    lines += ["endmodule", "", f'label "goal" = {goal};',
              f'label "safe" = x0!={rng.randint(0, top)};']
    return "\n".join(lines) + "\n"


def storm_exact(text: str, formula: str, folder: Path) -> Fraction:
    path = folder / "model.prism"
    path.write_text(text, encoding="utf-8")
    program = stormpy.parse_prism_program(str(path))
    parsed = stormpy.parse_properties(formula, program)
    model = stormpy.build_model[stormpy.Rational](program, parsed)
    result = stormpy.model_checking(model, parsed[0], only_initial_states=True)
    return Fraction(str(result.get_value(model.initial_states[0])))


def _compare(text: str, formula: str, folder: Path) -> None:
    want = storm_exact(text, formula, folder)
    run = check_prism_file(text, props_source=formula, keep="answers")
    (result,) = run.results
    assert result.certified, (formula, result, text)
    assert Fraction(result.lower) <= want <= Fraction(result.upper), (formula, want, text)
    assert abs(result.value - float(want)) <= 1e-9, (formula, result.value, want, text)


@pytest.mark.parametrize("seed", range(60))
def test_ltl_on_random_chains_matches_storm_exactly(seed: int, tmp_path: Path) -> None:
    rng = random.Random(seed)
    text = random_model_text(rng, "dtmc")
    for _ in range(2):
        _compare(text, f"P=? [ {random_formula(rng, rng.choice([2, 3]))} ]", tmp_path)


@pytest.mark.parametrize("seed", range(60))
def test_ltl_on_random_mdps_matches_storm_exactly(seed: int, tmp_path: Path) -> None:
    rng = random.Random(1000 + seed)
    text = (random_model(rng, modules=2) if seed % 4 == 0
            else random_model_text(rng, "mdp"))
    formula = random_formula(rng, rng.choice([2, 3]))
    for direction in ("min", "max"):
        _compare(text, f"P{direction}=? [ {formula} ]", tmp_path)


@pytest.mark.parametrize("seed", range(0, 60, 3))
def test_exact_ltl_equals_storms_rationals(seed: int, tmp_path: Path) -> None:
    """``--exact``: fraction for fraction, on chains and MDPs with probabilities like 1/3
    (not dyadic: the float model is then not the exact one)."""
    rng = random.Random(2000 + seed)
    kind = "dtmc" if seed % 2 else "mdp"
    text = random_model_text(rng, kind, dyadic=False)
    formula = random_formula(rng, rng.choice([2, 3]))
    queries = [f"P=? [ {formula} ]"] if kind == "dtmc" else [
        f"P{d}=? [ {formula} ]" for d in ("min", "max")]
    for query in queries:
        want = storm_exact(text, query, tmp_path)
        (result,) = check_prism_file(text, props_source=query, exact=True).results
        assert result.exact == want, (query, result.exact, want, text)
