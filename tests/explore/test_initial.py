"""The initial states of an ``init ... endinit`` block: each disjunct searched over the
values its single-variable conjuncts allow, equal to testing the whole domain."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from veribattery.errors import ModelError
from veribattery.explore.build.initial import initial_states
from veribattery.lang import flatten_model, parse_model
from veribattery.lang.nodes import FlatModel


def _flat(variables: str, init: str) -> FlatModel:
    return flatten_model(parse_model(f"mdp\nmodule m\n{variables}\n[] true -> true;\n"
                                     f"endmodule\ninit {init} endinit\n"))


def _python(init: str) -> str:
    """*init* (the atoms below) as a Python expression."""
    text = init.replace("<=", "\0le").replace(">=", "\0ge").replace("=", "==")
    text = text.replace("\0le", "<=").replace("\0ge", ">=")
    return text.replace("&", " and ").replace("|", " or ").replace("!", " not ").replace(
        "true", "True").replace("false", "False")


_VARS = "a : [0..3];\nb : [0..2];\nc : [1..4];"
_ATOMS = ["a=0", "a>1", "b=2", "b<2", "c=3", "c>=2", "a=b", "a+b=c", "true", "false",
          "!(c=1)"]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(st.sampled_from(_ATOMS), min_size=1, max_size=3), min_size=1,
                max_size=3))
def test_a_block_is_searched_as_the_whole_domain_would_be(terms: list[list[str]]) -> None:
    init = " | ".join("(" + " & ".join(term) + ")" for term in terms)
    model = _flat(_VARS, init)
    expected = _brute_force_text(model, init)
    if expected.shape[0] == 0:
        with pytest.raises(ModelError, match="satisfied by no state"):
            initial_states(model)
    else:
        assert np.array_equal(initial_states(model), expected)


def _brute_force_text(model: FlatModel, init: str) -> np.ndarray:
    """Every state of the domain that satisfies *init*, by Python's own evaluation."""
    names = model.variable_names
    found = [values for values in itertools.product(
        *(range(v.low, v.high + 1) for v in model.variables))
        if eval(_python(init), {}, dict(zip(names, values, strict=True)))]
    return np.array(found, dtype=np.int64).reshape(-1, len(names))


def test_pinned_variables_leave_a_huge_domain_unenumerated() -> None:
    # Twelve variables of 12 values and one of 8: 12^12 * 8 (7e13) states in the domain,
    # beyond what a search of it all could test; eight of them are initial.
    variables = "\n".join(f"x{i} : [0..11];" for i in range(12)) + "\npay : [0..7];"
    init = " & ".join(f"x{i}=0" for i in range(12))
    states = initial_states(_flat(variables, init))
    assert states.shape == (8, 13)
    assert states[:, -1].tolist() == list(range(8)) and not states[:, :-1].any()


def test_a_disjunct_over_the_whole_domain_is_one_pass() -> None:
    model = _flat("x : [0..9];\ny : [0..9];", "x=0 | x+y=3")
    assert initial_states(model).tolist() == [[0, y] for y in range(10)] + [
        [1, 2], [2, 1], [3, 0]]
