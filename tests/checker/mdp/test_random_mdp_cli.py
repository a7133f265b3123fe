"""Random PRISM ``mdp`` programs through :func:`check_prism_file`, against Storm.

hypothesis draws the programs: 2-3 modules with guarded, nondeterministic and
synchronised commands, self-loops and back edges (end components), a reward
structure with many zero rewards (zero-reward cycles) and the labels ``"goal"``
and ``"safe"``. Each is checked by veribattery's own builder and checker, in
floating point and with ``exact=True``, and by Storm (stormpy) from the same
text:

- floating point: the value agrees with Storm's default (value iteration) engine
  to 1e-6, Storm's rational value lies inside the certified interval, and Storm's
  float value does up to its own precision (1e-6);
- exact: the value equals Storm's exact engine's as a fraction, and the bounded
  forms ``P>=v``/``P>v`` with *v* the exact value itself are decided exactly (in
  floating point too: there the certified interval straddles *v*, and the bound
  is settled in exact arithmetic).

Derandomized, with a fixed example count: the same programs on every run.
"""

from __future__ import annotations

import math
import re
import tempfile
from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

stormpy = pytest.importorskip("stormpy")

from tests.checker.mdp.storm_mdp import build, storm_values  # noqa: E402
from veribattery.checker import CheckResult  # noqa: E402
from veribattery.checker.exact import ExactCheckResult  # noqa: E402
from veribattery.pipeline import check_prism_file  # noqa: E402

#: The quantities compared, each in its min and max form.
QUERIES = tuple(f"{kind}{o}=? [ {path} ]" for o in ("min", "max") for kind, path in (
    ("P", 'F "goal"'), ("P", '"safe" U "goal"'), ("P", 'G "safe"'),
    ("R{\"r\"}", 'F "goal"'), ("R{\"r\"}", "C")))

#: Storm's value iteration stops at 1e-6 (relative): its float values are that close.
STORM_PRECISION = 1e-6

#: Shrinking a failing program takes minutes: it is skipped (the program is printed).
PHASES = (Phase.explicit, Phase.reuse, Phase.generate)
SETTINGS = settings(max_examples=30, deadline=None, derandomize=True, database=None,
                    phases=PHASES, suppress_health_check=[HealthCheck.too_slow])

DYADIC = ((1,), (1, 1), (1, 3), (1, 1, 2), (3, 5))
THIRDS = ((1, 2), (1, 1, 1), (2, 3, 5), (1, 9))


@st.composite
def guards(draw: st.DrawFn, tops: list[int], own: int | None = None) -> str:
    """``true`` or one or two comparisons of variables (mostly the module's own)."""
    if draw(st.integers(0, 2)) == 0:
        return "true"
    atoms = []
    for _ in range(draw(st.integers(1, 2))):
        j = own if own is not None and draw(st.booleans()) else draw(
            st.integers(0, len(tops) - 1))
        op = draw(st.sampled_from(["=", "<", ">=", "!="]))
        atoms.append(f"x{j}{op}{draw(st.integers(0, tops[j]))}")
    return " & ".join(atoms)


@st.composite
def updates(draw: st.DrawFn, i: int, top: int, weights: tuple[int, ...]) -> str:
    """A distribution over next values of ``x{i}``: up, down, a jump, or staying put."""
    total = sum(weights)
    branches = []
    for w in weights:
        target = draw(st.sampled_from(  # success (top) and failure (top+1) often
            [f"min(x{i}+1,{top})", f"max(x{i}-1,0)", f"x{i}", str(top), str(top + 1),
             str(top + 1), *map(str, range(top))]))
        branches.append(f"{Fraction(w, total)}:(x{i}'={target})")
    return " + ".join(branches)


@st.composite
def mdp_programs(draw: st.DrawFn) -> str:
    """A random PRISM ``mdp`` program with a reward structure ``"r"`` and two labels.

    A module stops once its variable is at its top (success) or above it (failure);
    ``"goal"`` is module 0's success, and only states with ``x0`` below its top earn
    state rewards: many values are fractions, not 0, 1 or infinity."""
    modules = draw(st.integers(2, 3))
    tops = [draw(st.integers(1, 3)) for _ in range(modules)]
    shapes = DYADIC if draw(st.booleans()) else DYADIC + THIRDS
    lines = ["mdp", ""]
    used: set[str] = set()
    alone: list[str] = []  # the guards of unsynchronised commands
    for i, top in enumerate(tops):
        lines += [f"module m{i}", f"  x{i} : [0..{top + 1}] init 0;"]
        for _ in range(draw(st.integers(2, 4))):
            action = draw(st.sampled_from(["", "", "a", "b"]))
            used.add(action)
            guard = f"x{i}<{top} & {draw(guards(tops, i))}"  # at top or top+1: it stops
            alone += [guard] if not action else []
            lines.append(f"  [{action}] {guard} -> "
                         f"{draw(updates(i, top, draw(st.sampled_from(shapes))))};")
        lines += ["endmodule", ""]
    # No deadlocks: Storm gives a fixed deadlock no reward, PRISM (and veribattery) its
    # state reward forever. A stay where no unsynchronised command is enabled avoids them.
    last = len(tops) - 1
    lines.insert(len(lines) - 2, f"  [] !({' | '.join(alone) or 'false'}) -> (x{last}'=x{last});")
    lines.append('rewards "r"')
    for _ in range(draw(st.integers(1, 3))):
        value = draw(st.sampled_from(["0", "1", "2", "1/2", "1/3"]))
        label = draw(st.sampled_from(["", *(f"[{a}] " for a in sorted(used) if a)]))
        lines.append(f"  {label}x0<{tops[0]} & {draw(guards(tops))} : {value};")
    lines += ["endrewards", ""]
    lines.append(f'label "goal" = x0={tops[0]}{draw(st.sampled_from(["", " & x1!=0"]))};')
    lines.append(f'label "safe" = {draw(guards(tops))};')
    return "\n".join(lines) + "\n"


def _storm(text: str, *, exact: bool) -> list[Fraction | float]:
    """Storm's value of each of :data:`QUERIES` at the initial state."""
    built = build(text)
    initial = next(iter((built.exact if exact else built.floating).initial_states))
    return [storm_values(built, q, exact=exact)[initial] for q in QUERIES]


@SETTINGS
@given(text=mdp_programs())
def test_float_mode_agrees_with_storm(text: str) -> None:
    results = check_prism_file(text, selectors=QUERIES).results
    floats, exact = _storm(text, exact=False), _storm(text, exact=True)
    for result, storm_float, storm_exact in zip(results, floats, exact, strict=True):
        assert _agree(result, storm_float), (result.property.text, result.value, storm_float)
        assert _inside(result, storm_exact, slack=0.0 if _dyadic(text) else 1e-12), (
            result.property.text, result.lower, result.upper, storm_exact)
        assert _inside(result, storm_float, slack=STORM_PRECISION)


@SETTINGS
@given(text=mdp_programs())
def test_exact_mode_equals_storm_exact(text: str) -> None:
    results = check_prism_file(text, selectors=QUERIES, exact=True).results
    for result, storm in zip(results, _storm(text, exact=True), strict=True):
        assert isinstance(result, ExactCheckResult)
        assert (math.inf if result.exact is None else result.exact) == storm, (
            result.property.text, result.exact, storm, text)


@settings(max_examples=20, deadline=None, derandomize=True, database=None, phases=PHASES,
          suppress_health_check=[HealthCheck.too_slow])
@given(text=mdp_programs(), exact=st.booleans())
def test_bounds_at_the_exact_value_are_decided(text: str, exact: bool) -> None:
    """``Pmin>=v``/``Pmax>v`` with *v* Storm's exact optimum: true and false, in either
    mode (floating point settles the straddled bound in exact arithmetic)."""
    values = _storm(text, exact=True)
    picked = [(q, v) for q, v in zip(QUERIES, values, strict=True)
              if q.startswith("P") and isinstance(v, Fraction)][:2]
    props = [f"{q.split('=?')[0]}{op}{v} {q.split('=?')[1]}" for q, v in picked
             for op in (">=", ">")]
    results = check_prism_file(text, selectors=props, exact=exact).results
    assert [r.value for r in results] == [True, False] * len(picked), (props, text)


def _dyadic(text: str) -> bool:
    """Whether every fraction in *text* is a double: then the float model is the exact
    one, and Storm's rational value lies inside the certified interval exactly."""
    denominators = (int(d) for d in re.findall(r"\d+/(\d+)", text))
    return all(d & (d - 1) == 0 for d in denominators)


def _agree(result: CheckResult, storm: Fraction | float) -> bool:
    value = float(storm)
    if math.isinf(value) or math.isinf(result.value):
        return value == result.value
    return abs(result.value - value) <= STORM_PRECISION * max(1.0, abs(value))


def _inside(result: CheckResult, storm: Fraction | float, *, slack: float = 0.0) -> bool:
    """*storm* within the certified interval (widened by *slack*, relative, for Storm's
    float values; exactly, for its rationals)."""
    assert result.lower is not None and result.upper is not None
    if isinstance(storm, float) and math.isinf(storm):
        return result.upper == math.inf
    if slack:
        margin = slack * max(1.0, abs(float(storm)))
        return result.lower - margin <= float(storm) <= result.upper + margin
    low, high = result.lower, result.upper
    return (math.isinf(low) or Fraction(low) <= storm) and (
        math.isinf(high) or storm <= Fraction(high))


#: The queries whose exploration may stop early, with whether Storm's builder stops at
#: the same states (its terminal states: the targets of ``F`` and ``U`` and what falsifies
#: ``U``'s left side; for ``G`` the values alone are compared).
STOPPING = tuple((q, "G " not in q) for q in QUERIES if "[ C ]" not in q)


@settings(max_examples=15, deadline=None, derandomize=True, database=None, phases=PHASES,
          suppress_health_check=[HealthCheck.too_slow])
@given(text=mdp_programs())
def test_stopping_early_builds_what_storm_builds_with_the_same_values(text: str) -> None:
    """Each query alone, exploration stopped where it is decided: the value is the full
    build's, to the last bit, inside Storm's exact one, and the states are as many as
    Storm builds for that one property."""
    exact = _storm(text, exact=True)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.prism"
        path.write_text(text, encoding="utf-8")
        program = stormpy.parse_prism_program(str(path))
    for query, counted in STOPPING:
        early = check_prism_file(text, selectors=[query], stop_early=True)
        full = check_prism_file(text, selectors=[query])
        assert early.results[0].value == full.results[0].value, (query, text)
        assert _inside(early.results[0], exact[QUERIES.index(query)],
                       slack=0.0 if _dyadic(text) else 1e-12), (query, text)
        if counted:
            formula = stormpy.parse_properties(query, program)
            storm = stormpy.build_model(program, formula)
            assert early.model_summary["states"] == storm.nr_states, (query, text)
