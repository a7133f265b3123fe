"""Guards that only fix variables, found by index (explore/compile/equalities.py).

A model written state by state (as ``--export-induced`` writes the DTMC a strategy
induces) is built with its guards looked up, not evaluated on every layer. The index
must give exactly the guards' own enabledness: every model here is built twice, with
the index and with it switched off, and the two builds must be the same bit for bit
(states and their numbering, transitions, labels, results), with
every written form of an equality, bool variables, negative values, contradictory and
out-of-range guards, and several commands guarded by one state, in DTMCs (the group
expansion) and MDPs (the walk over a group's enabled commands, ``atoms``).
"""

from __future__ import annotations

import itertools
import random
from pathlib import Path

import numpy as np
import pytest

from veribattery import check_prism_file
from veribattery.explore.compile import equalities
from veribattery.explore.compile.equalities import EqualityIndex, equality_index
from veribattery.lang.nodes import Expr
from veribattery.lang.parser import parse_property


def parse_expression(text: str) -> Expr:
    return parse_property(text).formula


#: 512 valuations: with the repeated ones, more commands than the fused layer plan takes
#: (``plan.MAX_KINDS``), so that the build expands them group by group, by the index.
VALUATIONS = list(itertools.product(range(0, 16), range(-4, 12), (False, True)))


def _guard(x: int, y: int, b: bool, form: int) -> str:
    flag = ("b" if b else "!b") if form % 2 else f"b={'true' if b else 'false'}"
    if form == 2:
        return f"{x}=x & (y={y}) & {flag}"
    if form == 3:
        return f"{flag} & y={y} & x={x}"
    return f"x={x} & y={y} & {flag}"


def _update(rng: random.Random) -> str:
    x, y, b = rng.choice(VALUATIONS)
    return f"(x'={x})&(y'={y})&(b'={'true' if b else 'false'})"


def explicit_model(kind: str, seed: int) -> str:
    """Every valuation its own command (one in five with a second one), plus a
    contradictory and an out-of-range guard; two branches each, to random states."""
    rng = random.Random(seed)
    lines = [kind, "module m", "  x : [0..15] init 0;", "  y : [-4..11] init 0;",
             "  b : bool init false;"]
    for x, y, b in VALUATIONS:
        for _ in range(2 if rng.random() < 0.2 else 1):
            action = rng.choice(["a", "b2", "c"]) if kind == "mdp" else ""
            lines.append(f"  [{action}] {_guard(x, y, b, rng.randrange(4))} -> "
                         f"0.25:{_update(rng)} + 0.75:{_update(rng)};")
    lines.append("  [] x=1 & x=2 & y=0 & b -> true;")  # holds nowhere
    lines.append("  [] x=19 & y=0 & b -> true;")  # outside x's range: nowhere
    lines += ["endmodule", 'label "far" = x=15 & y=11;', 'rewards "r" x>1 : 1; endrewards']
    return "\n".join(lines) + "\n"


def _built(text: str, kind: str, props: tuple[str, ...] = ()) -> tuple[object, ...]:
    props = props or (('Pmax=? [ F "far" ]', 'Rmin=? [ F "far" ]') if kind == "mdp"
                      else ('P=? [ F "far" ]', 'R=? [ F "far" ]'))
    run = check_prism_file(text, selectors=props, keep="states")
    model = run.mdp if kind == "mdp" else run.dtmc  # type: ignore[union-attr]
    T = model.transitions
    labels = tuple((n, np.asarray(model.labels[n]).tobytes()) for n in sorted(model.labels))
    return (T.indptr.tobytes(), T.indices.tobytes(), T.data.tobytes(),
            np.asarray(model.states).tobytes(), labels,
            tuple(repr(r.value) for r in run.results))


@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
@pytest.mark.parametrize("seed", range(6))
def test_an_indexed_build_is_the_evaluated_one(kind: str, seed: int,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    text = explicit_model(kind, seed)
    looked_up = _counting(monkeypatch)
    indexed = _built(text, kind)
    assert looked_up[0] > 0  # (the build went through the index)
    monkeypatch.setattr(equalities, "MIN_COMMANDS", 10**9)  # every guard evaluated
    assert _built(text, kind) == indexed


def _counting(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """A counter of the index's lookups."""
    calls = [0]
    enabled = EqualityIndex.enabled

    def counted(self: EqualityIndex, states: np.ndarray) -> np.ndarray:
        calls[0] += 1
        return enabled(self, states)

    monkeypatch.setattr(EqualityIndex, "enabled", counted)
    return calls


def test_the_index_enables_what_the_guards_hold() -> None:
    ranges = {"x": (0, 15), "y": (-4, 11), "b": (0, 1)}
    names = ("x", "y", "b")
    texts = [_guard(x, y, b, form) for (x, y, b), form in
             zip(VALUATIONS, itertools.cycle(range(4)), strict=False)]
    texts += ["x=1 & x=2 & b", "x=19 & y=0 & b", "x=1 & b", "x=1 & x=1 & y=0 & !b"]
    index = equality_index([parse_expression(t) for t in texts], names, ranges)
    assert isinstance(index, EqualityIndex)
    grid = np.array([(x, y, int(b)) for x, y, b in VALUATIONS], dtype=np.int64)
    enabled = index.enabled(grid)
    env = [dict(zip(names, row, strict=True)) for row in grid.tolist()]
    for j, text in enumerate(texts):
        python = text.replace("&", " and ").replace("!b", "not b").replace("=", "==")
        python = python.replace("true", "1").replace("false", "0")
        expected = [bool(eval(python, {}, values)) for values in env]
        assert enabled[:, j].tolist() == expected, text


@pytest.mark.parametrize("guard", ["x<2 & y=0", "x=1 | y=0", "x=y", "true", "x=N"])
def test_other_guards_leave_the_part_unindexed(guard: str) -> None:
    guards = [parse_expression("x=1 & y=0")] * 40 + [parse_expression(guard)]
    assert equality_index(guards, ("x", "y"), {"x": (0, 3), "y": (-2, 1)}) is None


def test_few_commands_are_not_indexed() -> None:
    guards = [parse_expression(f"x={i % 4}") for i in range(equalities.MIN_COMMANDS - 1)]
    assert equality_index(guards, ("x",), {"x": (0, 3)}) is None


def test_a_written_induced_model_builds_as_before(monkeypatch: pytest.MonkeyPatch) -> None:
    """The form ``--export-induced`` writes (a 3 x 2 farm's induced DTMC, vendored)."""
    model = Path(__file__).parent / "data" / "induced_small.prism"
    text = model.read_text(encoding="utf-8")
    props = ('P=? [ F "success" ]', 'R{"mt"}=? [ F "done" ]')
    looked_up = _counting(monkeypatch)
    indexed = _built(text, "dtmc", props)
    assert looked_up[0] > 0
    assert indexed[-1] == ("0.9384661626325166", "664.2969828003883")  # synthesize's
    monkeypatch.setattr(equalities, "MIN_COMMANDS", 10**9)
    assert _built(text, "dtmc", props) == indexed
