"""The PRISM example models of the peer suite: counts from its manifest, and Storm's DTMC."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import require_shared
from tests.explore.storm import assert_same, build
from tests.peer_manifests import assert_enough, fail_missing, manifest, missing
from veribattery.explore import DTMC, build_dtmc
from veribattery.lang.parser import parse_model
from veribattery.lang.semantics import flatten_model

SUITE = Path("prism-examples")


@dataclass(frozen=True)
class Case:
    """One model with one constant setting and its expected counts."""

    model: str
    constants: dict[str, str]
    states: int
    transitions: int
    initial_states: int

    def __str__(self) -> str:
        consts = ",".join(f"{k}={v}" for k, v in self.constants.items())
        return f"{Path(self.model).stem}[{consts}]" if consts else Path(self.model).stem


def _cases() -> list[Any]:
    data = manifest(str(SUITE))
    if data is None:
        return [missing(str(SUITE), None)]
    return [
        Case(m["model"], s["constants"], s["states"], s["transitions"], s["initial_states"])
        for m in data["models"]
        for s in m["settings"]
    ]


CASES = _cases()
#: (model, constants) settings the manifest lists (counted 2026-11-26): a floor.
SETTINGS = 9


def _build(case: Case) -> tuple[Path, DTMC]:
    path = require_shared() / SUITE / case.model
    return path, build_dtmc(flatten_model(parse_model(path), case.constants))


def test_every_setting_of_the_manifest_is_built() -> None:
    found = sum(isinstance(case, Case) for case in CASES)
    assert_enough(found, SETTINGS, f"{SUITE} (model, constants) settings")


@pytest.mark.parametrize("case", CASES, ids=str)
def test_counts_match_manifest(case: Case | None) -> None:
    if case is None:
        fail_missing(str(SUITE))
    _, dtmc = _build(case)
    assert dtmc.num_states == case.states
    assert dtmc.num_transitions == case.transitions
    assert dtmc.initial.size == case.initial_states
    assert dtmc.labels["init"].sum() == case.initial_states


@pytest.mark.parametrize("case", CASES, ids=str)
def test_same_chain_as_storm(case: Case | None) -> None:
    if case is None:
        fail_missing(str(SUITE))
    path, dtmc = _build(case)
    assert_same(dtmc, build(path, case.constants, dtmc.variable_names))


MIXED = """dtmc
module M
  x : [0..3] init 0;
  [] x<3 -> 0.5:(x'=x+1) + 0.5:true;
  [] x>0 -> 1:(x'=x-1);
  [a] x=3 -> 1:(x'=0);
endmodule
module N
  y : bool init false;
  [a] true -> 0.3:(y'=!y) + 0.7:true;
  [a] y -> 1:(y'=false);
  [b] y -> 1:(y'=false);
endmodule
rewards "r"
  x>0 : x;
  [a] true : 10;
  [] x>1 : 1;
  [b] true : 100;
endrewards
"""


def test_uniform_choices_sync_and_transition_rewards_match_storm(tmp_path: Path) -> None:
    path = tmp_path / "mixed.pm"
    path.write_text(MIXED)
    dtmc = build_dtmc(flatten_model(parse_model(path), {}))
    assert dtmc.nondeterministic > 0
    assert_same(dtmc, build(path, {}, dtmc.variable_names))
