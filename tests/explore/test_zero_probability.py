"""A branch of probability 0 is no transition, and its target no state, in every builder:
the DTMC's and the MDP's, in floating point and in exact rationals (PRISM and Storm
build such a model alike). The MDP builder used to number the target (a spurious state,
reported as a deadlock), and ``--exact`` on a DTMC then refused the model outright."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from veribattery.cli import cli
from veribattery.explore.build.mdp import build_mdp
from veribattery.lang import flatten_model, parse_model

#: From x=0 a branch of probability 0 (a literal, then an expression that is 0 there)
#: leads to x=3 / x=2, which no other branch reaches: 2 states, 2 transitions.
BODY = """
module a
  x : [0..3] init 0;
  [] x=0 -> 0:(x'=3) + 1:(x'=1);
  [] x=1 -> (1-x):(x'=2) + x:(x'=1);
endmodule
"""


def _write(tmp_path: Path, kind: str) -> Path:
    path = tmp_path / f"zero.{'nm' if kind == 'mdp' else 'pm'}"
    path.write_text(kind + "\n" + BODY)
    return path


def test_the_mdp_builder_drops_the_target() -> None:
    built = build_mdp(flatten_model(parse_model("mdp\n" + BODY), {}))
    assert sorted(int(s[0]) for s in built.states) == [0, 1]
    assert built.transitions.nnz == 2 and built.deadlocks == 0


@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
@pytest.mark.parametrize("exact", [False, True])
def test_both_builders_float_and_exact(tmp_path: Path, kind: str, exact: bool) -> None:
    prop = "P=? [ F x=1 ]" if kind == "dtmc" else "Pmax=? [ F x=1 ]"
    result = CliRunner().invoke(cli, ["prism", str(_write(tmp_path, kind)), "--property",
                                      prop, "--json", *(["--exact"] if exact else [])])
    assert result.exit_code == 0, result.output
    assert '"states": 2' in result.stdout and '"transitions": 2' in result.stdout
    assert '"deadlocks": 0' in result.stdout
    assert ('"exact": "1"' in result.stdout) if exact else ('"value": 1.0' in result.stdout)


@pytest.mark.parametrize("kind", ["dtmc", "mdp"])
def test_storm_builds_the_same_model(tmp_path: Path, kind: str) -> None:
    stormpy = pytest.importorskip("stormpy", reason="stormpy is needed for the cross-check")
    model = stormpy.build_model(stormpy.parse_prism_program(str(_write(tmp_path, kind))))
    assert (model.nr_states, model.nr_transitions) == (2, 2)
