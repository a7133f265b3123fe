"""The fast parser against lark, the grammar of record: same nodes, same spans, or lark.

Every node is compared through ``repr``, which shows the spans and property texts
that node equality ignores. Where lark rejects a text, the fast path must not accept
it (it hands the text to lark, which writes the message).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import PEER_TESTS
from tests.lang.helpers import DTMC_SUITES, tree
from veribattery.errors import PrismSyntaxError, VeribatteryError
from veribattery.lang import parse_model, parse_property
from veribattery.lang.fastparse import Fallback, parse_fast
from veribattery.lang.parser import _parse_with_lark

ROOT = Path(__file__).resolve().parents[2]
_MODEL_SUFFIXES = (".prism", ".pm", ".nm", ".sm")
_PROPS_SUFFIXES = (".props", ".pctl")


def _corpus() -> list[Any]:
    """Every model and properties file of the tests and the peer suites."""
    roots = [ROOT / "tests", *(PEER_TESTS / suite for suite in DTMC_SUITES)]
    files = sorted(
        path for root in roots if root.is_dir() for path in root.rglob("*")
        if path.name.endswith(_MODEL_SUFFIXES + _PROPS_SUFFIXES)
    )
    return [pytest.param(path, id=str(path.relative_to(path.parents[2]))) for path in files]


def _start(name: str) -> str:
    return "start_model" if name.endswith(_MODEL_SUFFIXES) else "start_props"


def _both(text: str, start: str) -> tuple[str | None, str | None]:
    """``repr`` of the fast and the lark result (None: fell back / rejected)."""
    try:
        fast: str | None = tree(parse_fast(text, "f", start))
    except Fallback:
        fast = None
    try:
        lark: str | None = tree(_parse_with_lark(text, "f", start))
    except VeribatteryError:
        lark = None
    return fast, lark


def _assert_agree(text: str, start: str) -> bool:
    """Fast equals lark wherever fast answers; True if it did."""
    fast, lark = _both(text, start)
    if fast is not None:
        assert lark is not None, f"fast parser accepts what lark rejects: {text!r}"
        assert fast == lark
    return fast is not None


@pytest.mark.parametrize("path", _corpus())
def test_fast_parser_builds_what_lark_builds(path: Path) -> None:
    _assert_agree(path.read_text(encoding="utf-8"), _start(path.name))


def test_the_corpus_is_real_and_mostly_on_the_fast_path() -> None:
    paths = [p.values[0] for p in _corpus()]
    assert len(paths) >= 20
    fast = sum(_assert_agree(p.read_text(encoding="utf-8"), _start(p.name)) for p in paths)
    assert fast >= 0.9 * len(paths)


CONFIGS = sorted((ROOT / "configs").rglob("*.yaml"))


def test_every_config_is_in_the_corpus() -> None:
    """configs/example.yaml and the paper's seven cases, at least."""
    assert len(CONFIGS) >= 8, CONFIGS


@pytest.mark.parametrize("config", CONFIGS, ids=str)
def test_mission_models_take_the_fast_path(config: Path) -> None:
    from veribattery.config import load_config
    from veribattery.render import render_model, render_properties

    cfg = load_config(config)
    assert _assert_agree(render_model(cfg), "start_model")
    assert _assert_agree(render_properties(cfg), "start_props")


@pytest.mark.parametrize(
    "text",
    [
        "P=? [ F<=5 (x=1) ]", '"a": P>=0.5 [ !a U<=3 b ]', "R{\"r\"}=? [ C<=-2+k ]",
        "R{2}min=? [ I=3 ]", "S=? [ x>1 ]", "P=? [ X x=1 ]", "-(a)^-b^2*c", "!!a = b & c",
        "a ? b ? c : d : e", "min(a, max(b, c)) + func(pow, 2, 3)", "P=? [ F x=1 || F y=2 ]",
        'R{"t"}=? [ F "done" || F "ok" ] ', "filter(forall, P>0.5 [ F a ], b)",
        "filter(+, x)", "E [ F a ]", "A [ G a ]", "T=? [ F a ]", "P=? [ F{\"r\"}<=5 a ]",
        "P=? [ a U{\"r\"}<3 b ]", "P=? [ F a {b}{min}{max} ]", "P=? [ F [2,4] a ]",
        "P=? [ a R b ]", "P=? [ a W>=2 b ]", "(((x)))", "1.5e3 <=> .5 => 2E-1",
        "F", "a & F", "x U", "P=?", "P=? [", "min(x)", "U=2", "x y", "\"a\":", "1..2",
    ],
)
def test_property_corners(text: str) -> None:
    _assert_agree(text, "start_property")
    _assert_agree(text, "start_props")


_NAMES = st.sampled_from(["x", "y", "s_1", "F", "U", "R", "C", "min", "true", "T", "E"])
_ATOMS = st.one_of(
    _NAMES, st.sampled_from(["0", "12", "0.5", ".5", "1e3", "2.5E-2", '"done"', "false"])
)
_BINARY = st.sampled_from(
    ["=>", "<=>", "|", "&", "=", "!=", "<", "<=", ">", ">=", "+", "-", "*", "/", "^",
     " U ", " W ", " R ", "||"]
)
_SPACE = st.sampled_from(["", " ", "\n", "  // c\n"])


def _combine(children: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
    return st.one_of(
        st.tuples(children, _SPACE, _BINARY, _SPACE, children).map("".join),
        st.tuples(st.sampled_from(["-", "!", "F ", "X ", "G ", "F<=2 "]), children).map("".join),
        children.map(lambda c: f"({c})"),
        st.tuples(children, children, children).map(lambda t: f"{t[0]} ? {t[1]} : {t[2]}"),
        st.tuples(st.sampled_from(["min", "max", "pow", "floor"]), children).map(
            lambda t: f"{t[0]}({t[1]}, 1)"),
        st.tuples(st.sampled_from(["P=? ", "P>0.5", "R{\"r\"}=?", "S<0.1", "Pmax=?"]),
                  children).map(lambda t: f"{t[0]}[ {t[1]} ]"),
    )


@settings(max_examples=300, deadline=None)
@given(st.recursive(_ATOMS, _combine, max_leaves=12))
def test_generated_expressions_agree_with_lark(text: str) -> None:
    _assert_agree(text, "start_property")


@settings(max_examples=100, deadline=None)
@given(st.recursive(_ATOMS, _combine, max_leaves=8))
def test_generated_guards_agree_with_lark(guard: str) -> None:
    command = f"[a] {guard} -> 0.5:(x'=1) + 0.5:true;"
    model = f"dtmc\nmodule m\n x : [0..3] init 0;\n {command}\nendmodule\n"
    _assert_agree(model, "start_model")


def test_errors_are_lark_messages_with_a_caret() -> None:
    with pytest.raises(PrismSyntaxError) as caught:
        parse_model("dtmc\nmodule m\n x : [0..2] init 0;\n [] x=0 -> (x'=1;\nendmodule\n",
                    name="bad.prism")
    message = str(caught.value)
    assert message.startswith("bad.prism:4:")
    assert "unexpected token ';'" in message and "^" in message
    with pytest.raises(PrismSyntaxError, match="unexpected end of input"):
        parse_property("P=? [ F ")
