"""The MDP builder's one-pass chunks (the fused layer plan) give the group-by-group
build bit for bit: the same states in the same numbering, rows, entries and actions."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import PEER_TESTS
from tests.peer_manifests import assert_enough, fail_missing, manifest, missing
from veribattery.explore.build import mdp as mdp_module
from veribattery.explore.build.fused import LayerPlan
from veribattery.explore.build.mdp import BuiltMdp, build_mdp
from veribattery.lang import flatten_model, parse_model
from veribattery.lang.nodes import FlatModel

MODELS = {
    # two modules synchronising on [s] with several commands a part (a product of
    # choices, some disabled), lone commands, deadlocks at x=3, and a zero-probability
    # branch whose target (z=1: set by no other branch) is no state
    "product": """mdp
module a
  x : [0..3] init 0;
  z : [0..1] init 0;
  [s] x<3 -> 0.3:(x'=x+1) + 0.7:true;
  [s] x>0 & x<3 -> (x'=x-1);
  [] x=0 & z=0 -> 0:(z'=1) + 1:(x'=1);
endmodule
module b
  y : [0..2] init 0;
  [s] y<2 -> 0.6:(y'=y+1) + 0.4:(y'=0);
  [s] y=2 & x<3 -> (y'=0);
  [t] y>=1 & x<3 -> 1/(y+1):(y'=y-1) + 1-1/(y+1):true;
endmodule
rewards "r"
  [s] true : 1;
  [t] true : 2;
endrewards
""",
    # state-dependent probabilities, a division guarded by its command, booleans
    "expressions": """mdp
const int N = 6;
module c
  n : [0..N] init 0;
  f : bool init false;
  [go] n<N -> n/N:(n'=n+1) + 1-n/N:(n'=n+1)&(f'=!f);
  [go] n=N -> (n'=floor(N/(n-N+1)) - N);
  [] f & n=N -> (f'=false);
  [] n<N -> (n'=N);
endmodule
module d
  m : [0..N] init 1;
  [go] m>0 -> (m'=min(N, floor(12/m)));
  [go] m=0 -> (m'=n);
endmodule
""",
}


def _built(model: FlatModel, fused: bool, monkeypatch: pytest.MonkeyPatch) -> BuiltMdp:
    with monkeypatch.context() as patch:
        if not fused:
            patch.setattr(mdp_module, "layer_plan", lambda program: None)
        return build_mdp(model)


def _assert_same_build(model: FlatModel, monkeypatch: pytest.MonkeyPatch) -> int:
    """Both builds equal; the number of chunks the fused path expanded."""
    taken = []
    original = LayerPlan.branches

    def counted(plan: LayerPlan, states: np.ndarray) -> Any:
        found = original(plan, states)
        taken.append(found is not None)
        return found

    with monkeypatch.context() as patch:
        patch.setattr(LayerPlan, "branches", counted)
        got = _built(model, True, monkeypatch)
    want = _built(model, False, monkeypatch)
    np.testing.assert_array_equal(got.states, want.states)
    np.testing.assert_array_equal(got.initial, want.initial)
    np.testing.assert_array_equal(got.row_groups, want.row_groups)
    np.testing.assert_array_equal(got.transitions.indptr, want.transitions.indptr)
    np.testing.assert_array_equal(got.transitions.indices, want.transitions.indices)
    assert got.transitions.data.tobytes() == want.transitions.data.tobytes()  # bit for bit
    np.testing.assert_array_equal(got.choice_actions, want.choice_actions)
    assert got.actions == want.actions and got.deadlocks == want.deadlocks
    for mine, theirs in zip(got.rewards, want.rewards, strict=True):
        assert mine.choice.tobytes() == theirs.choice.tobytes()
        assert mine.state.tobytes() == theirs.state.tobytes()
    assert got.labels.keys() == want.labels.keys()
    return sum(taken)


@pytest.mark.parametrize("name", MODELS)
def test_fused_mdp_equals_group_by_group(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    model = flatten_model(parse_model(MODELS[name]), {})
    assert _assert_same_build(model, monkeypatch) > 0  # the fused path is exercised


def test_product_by_hand(monkeypatch: pytest.MonkeyPatch) -> None:
    """(x, z, y) = (0, 0, 0): [s] 1x1 (0.3/0.7 times 0.6/0.4) and the lone [] (its
    zero-probability branch no entry, and its target no state: as PRISM and Storm)."""
    built = _built(flatten_model(parse_model(MODELS["product"]), {}), True, monkeypatch)
    names = [tuple(int(v) for v in s) for s in built.states]
    assert names[0] == (0, 0, 0)
    start, stop = int(built.row_groups[0]), int(built.row_groups[1])
    rows = built.transitions[start:stop].toarray()
    found = [{names[j]: rows[r, j] for j in np.flatnonzero(rows[r])} for r in range(stop - start)]
    assert len(found) == 2
    assert {(1, 0, 0): 1.0} in found
    product = next(row for row in found if len(row) == 4)
    assert product == pytest.approx({(1, 0, 1): 0.18, (1, 0, 0): 0.12, (0, 0, 1): 0.42,
                                     (0, 0, 0): 0.28})
    assert all(name[1] == 0 for name in names)  # z=1 is reached by probability 0 only
    # x=3: [s] is disabled in module a, [] too -- a deadlock, its self-loop its one row
    for state, name in enumerate(names):
        if name[0] == 3:
            row = int(built.row_groups[state])
            assert built.row_groups[state + 1] - row == 1
            assert built.transitions[row].indices.tolist() == [state]
    assert built.deadlocks == sum(name[0] == 3 for name in names) > 0


def _peer_cases(limit: int) -> list[Any]:
    data = manifest("prism-mdp")
    if data is None:
        return [missing("prism-mdp", None)]
    seen: dict[str, Any] = {}
    for entry in data["entries"]:
        if entry["states"] is None or entry["states"] > limit:
            continue
        key = f"{entry['model']}{sorted(entry['constants'].items())}"
        seen.setdefault(key, pytest.param((entry["model"], entry["constants"]), id=key))
    return list(seen.values())


PEER = _peer_cases(20_000)


def test_enough_peer_models_are_compared() -> None:
    """The prism-mdp suite had 31 model settings of at most 20,000 states when this was
    written."""
    assert_enough(sum(p.values[0] is not None for p in PEER), 31, "prism-mdp settings")


@pytest.mark.parametrize("case", PEER)
def test_fused_mdp_equals_group_by_group_on_peer_models(
    case: tuple[str, dict[str, str]] | None, monkeypatch: pytest.MonkeyPatch,
) -> None:
    if case is None:
        fail_missing("prism-mdp")
    path = PEER_TESTS / "prism-mdp" / Path(case[0])
    _assert_same_build(flatten_model(parse_model(path), case[1]), monkeypatch)


QCOMP = Path(__file__).resolve().parents[2] / "bench" / "qcomp"


@pytest.mark.parametrize(("model", "constants"), [
    ("consensus/consensus.4.prism", {"K": "2"}),
    ("csma/csma.3-2.prism", {}),
    ("zeroconf/zeroconf.prism", {"N": "20", "K": "2", "reset": "false"}),
])
def test_fused_mdp_equals_group_by_group_on_qcomp(
    model: str, constants: dict[str, str], monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Larger models of many chunks (22,656 to 89,586 states), synchronising modules."""
    flat = flatten_model(parse_model(QCOMP / model), constants)
    assert _assert_same_build(flat, monkeypatch) > 3
