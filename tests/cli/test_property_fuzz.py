"""Mangled properties meet a one-line error or an answer, never a traceback, and the
float and exact engines agree wherever both answer.

Each example takes a well-formed property on a DTMC or an MDP example and mangles it:
words swapped within their class, operators put before atoms. A fuzzer of this kind found
four defects (the ``@example`` cases): ``--exact`` typed a closed property only after
evaluating it (``true + 1`` answered 2, ``- true`` numpy's TypeError), an LTL operand was
never typed, a filter suffix of path formulas ended in lark's VisitError, and a closed
value beyond the doubles under ``--exact`` in an OverflowError. This keeps a few hundred
such inputs in the suite.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from click.testing import CliRunner, Result
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from veribattery.cli import cli

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

BASES = {
    "prism/dice.pm": [
        "P=? [ F s=7 & d=6 ]", "R=? [ F s=7 ]", "P=? [ s<3 U d=2 ]", "S=? [ d=1 ]",
        "P=? [ G F s=7 ]", "P=? [ F<=3 s=7 ]", "R=? [ C<=4 ]", "P=? [ F d=1 || F d<3 ]",
        "P=? [ (F d=1) & (G d!=2) ]", "filter(avg, P=? [ F d=6 ], s=0)", "P>=1/6 [ F d=6 ]",
    ],
    "mdp/robot.nm": [
        'Pmax=? [ F "goal" ]', 'R{"steps"}min=? [ F "goal" ]', "Rmax=? [ C<=3 ]",
        'Pmin=? [ G !"broken" ]', 'Pmax=? [ G F "goal" ]', 'R{"steps"}max=? [ F (X "goal") ]',
        'E [ F "goal" ]', 'filter(max, Pmax=? [ F "goal" ], x<2)', 'R{"time"}max=? [ I=2 ]',
    ],
}
#: Words a mangling may put in place of a word of the same class, or before an atom.
SWAPS = {
    "temporal": ["F", "G", "X", "F<=3", "G>=1", "F[1,3]", "X X", "G F", "F G"],
    "binary": ["U", "W", "R", "U<=2", "&", "|", "=>", "<=>"],
    "operator": ["P=?", "Pmax=?", "Pmin=?", "P>=0.5", "P<1/3", "R=?", "Rmax=?", "S=?",
                 "A", "E"],
    "atom": ["s=7", "d=6", "s<3", "x=3", "x<2", '"goal"', '"broken"', "true", "false",
             "!(s=1)", "(d=1 | d=2)", "s+1>2", "- true", "1e308^7>s", "s=0 {s=0}"],
    "before atom": ["!", "F", "G", "X", "(X", "1 -"],
}


def _class_of(word: str) -> str:
    if word in ("F", "G", "X") or (word[:1] in "FGX" and word[1:2] in "<>[="):
        return "temporal"
    if word in ("U", "W", "R", "&", "|", "=>", "<=>"):
        return "binary"
    if word[:1] in "PRSAE" and ("=?" in word or word in ("A", "E") or word[1:2] in "<>=m"):
        return "operator"
    return "atom" if word not in ("[", "]", "(", ")", ",") else "bracket"


@st.composite
def mangled(draw: st.DrawFn) -> tuple[str, str]:
    """A base property with one to three of its words swapped for another of their class
    (an atom for an atom, a temporal operator for one), or an atom given an operator in
    front: most manglings still parse, so both engines go on to answer."""
    model = draw(st.sampled_from(sorted(BASES)))
    words = draw(st.sampled_from(BASES[model])).split()
    for _ in range(draw(st.integers(1, 3))):
        at = draw(st.integers(0, len(words) - 1))
        kind = _class_of(words[at])
        if kind == "bracket":
            continue
        if kind == "atom" and draw(st.booleans()):
            words.insert(at, draw(st.sampled_from(SWAPS["before atom"])))
        else:
            words[at] = draw(st.sampled_from(SWAPS[kind]))
    return model, " ".join(words)


def _run(model: str, prop: str, *extra: str) -> Result:
    return CliRunner().invoke(cli, ["prism", str(EXAMPLES / model), "--property", prop,
                                    "--json", *extra])


def _answered_or_refused(result: Result) -> None:
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception  # its traceback is the report
    assert result.exit_code in (0, 2)
    if result.exit_code == 2:
        (line,) = result.stderr.strip().splitlines()
        assert line.startswith("error: ")


def _number(value: object) -> float | bool | None:
    if value is None or isinstance(value, bool):
        return value
    return float(value) if isinstance(value, int | float | str) else None


@settings(max_examples=250, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(mangled())
@example(("prism/dice.pm", "- true"))
@example(("mdp/robot.nm", "true + 1"))
@example(("prism/dice.pm", "P>=1 [ G F -(s=1|s=4) ]"))
@example(("prism/dice.pm", "Pmax=? [ F s=1 {s=0 & X W s=0} ]"))
@example(("prism/dice.pm", "A [ F s= 1e308 ^ 7 ]"))
def test_a_mangled_property_is_answered_or_refused_alike_in_floats_and_exactly(
        case: tuple[str, str]) -> None:
    model, prop = case
    floats, exact = _run(model, prop), _run(model, prop, "--exact")
    _answered_or_refused(floats)
    _answered_or_refused(exact)
    if floats.exit_code or exact.exit_code:
        return
    (ours,), (rational,) = (json.loads(r.stdout)["results"] for r in (floats, exact))
    a, b = _number(ours["value"]), _number(rational["value"])
    if isinstance(a, float) and isinstance(b, float) and math.isfinite(b):
        low, high = ours.get("bounds") or (a, a)
        assert low <= b <= high or math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)
    elif a is not None and b is not None:
        assert a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(float(b)))
