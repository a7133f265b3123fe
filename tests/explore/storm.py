"""Build a model with stormpy and line it up with one of ours, state by state."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from veribattery.explore import DTMC

stormpy = pytest.importorskip("stormpy", reason="stormpy is needed for the cross-checks")


@dataclass(frozen=True)
class StormModel:
    """Storm's DTMC: states (as our variable order), matrix, reward vectors by name."""

    states: np.ndarray
    matrix: sp.csr_matrix
    state_rewards: dict[str, np.ndarray]
    action_rewards: dict[str, np.ndarray]
    initial: list[int]


def build(path: Path, constants: Mapping[str, str], names: Sequence[str]) -> StormModel:
    """Build *path* with Storm (all rewards, state valuations)."""
    program = stormpy.parse_prism_program(str(path))
    if constants:
        text = ",".join(f"{k}={v}" for k, v in constants.items())
        program, _ = stormpy.instantiate_constants(program, text)
    model = stormpy.build_model(program, options=stormpy.BuilderOptions(build_full=True))
    return StormModel(
        _valuations(program, model, names),
        _matrix(model),
        {
            k: np.array(r.state_rewards)
            for k, r in model.reward_models.items()
            if r.has_state_rewards
        },
        {
            k: np.array(r.state_action_rewards)
            for k, r in model.reward_models.items()
            if r.has_state_action_rewards
        },
        list(model.initial_states),
    )


def _valuations(program: object, model: object, names: Sequence[str]) -> np.ndarray:
    variables = {}
    for v in list(program.global_integer_variables) + list(program.global_boolean_variables):  # type: ignore[attr-defined]
        variables[v.name] = v
    for module in program.modules:  # type: ignore[attr-defined]
        for v in list(module.integer_variables) + list(module.boolean_variables):
            variables[v.name] = v
    valuations = model.state_valuations  # type: ignore[attr-defined]
    rows = np.zeros((model.nr_states, len(names)), dtype=np.int64)  # type: ignore[attr-defined]
    for s in range(rows.shape[0]):
        for i, name in enumerate(names):
            var = variables[name].expression_variable
            if var.has_boolean_type():
                rows[s, i] = int(valuations.get_boolean_value(s, var))
            else:
                rows[s, i] = valuations.get_int64_value(s, var)
    return rows


def _matrix(model: object) -> sp.csr_matrix:
    entries = [
        (s, e.column, e.value)
        for s in range(model.nr_states)  # type: ignore[attr-defined]
        for e in model.transition_matrix.get_row(s)  # type: ignore[attr-defined]
    ]
    r, c, v = zip(*entries, strict=True)
    n = model.nr_states  # type: ignore[attr-defined]
    return sp.csr_matrix((v, (r, c)), shape=(n, n))


def assert_same(ours: DTMC, storm: StormModel) -> None:
    """Same states, same transition probabilities, same rewards (via valuations)."""
    assert ours.num_states == storm.states.shape[0]
    index = {tuple(row): i for i, row in enumerate(ours.states.tolist())}
    perm = np.array([index[tuple(row)] for row in storm.states.tolist()])  # storm -> ours
    assert sorted(perm[storm.initial].tolist()) == sorted(ours.initial.tolist())
    p = ours.transitions[perm][:, perm]
    assert p.nnz == storm.matrix.nnz
    assert abs(p - storm.matrix).max() <= 1e-12
    for structure in ours.rewards:
        name = structure.name or ""
        state = storm.state_rewards.get(name, np.zeros(ours.num_states))
        action = storm.action_rewards.get(name, np.zeros(ours.num_states))
        np.testing.assert_allclose(structure.state[perm], state, rtol=1e-12)
        np.testing.assert_allclose(structure.transition[perm], action, rtol=1e-12)
