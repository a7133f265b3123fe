"""Storm as the oracle of the MDP kernels: build a PRISM ``mdp`` text with stormpy and
convert Storm's own sparse model into an :class:`MDP`, so that states match one to one.

Import this module only after ``pytest.importorskip("stormpy")``.
"""

from __future__ import annotations

import math
import random
import tempfile
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
import stormpy

from veribattery.checker.mdp import MDP, MdpRewards


@dataclass(frozen=True)
class Built:
    """One model as Storm built it (float and exact) and as an :class:`MDP`."""

    program: Any
    floating: Any
    exact: Any
    mdp: MDP


def build(text: str) -> Built:
    """Build *text* with Storm in float and rational arithmetic."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.prism"
        path.write_text(text, encoding="utf-8")
        program = stormpy.parse_prism_program(str(path))
    options = stormpy.BuilderOptions()
    options.set_build_choice_labels(True)
    options.set_build_state_valuations(True)
    options.set_build_all_reward_models(True)
    options.set_build_all_labels(True)
    floating = stormpy.build_model[float](program, options=options)
    exact = stormpy.build_model[stormpy.Rational](program, options=options)
    return Built(program, floating, exact, to_mdp(floating))


def to_mdp(model: Any) -> MDP:
    """Storm's sparse MDP as an :class:`MDP` (same state and choice numbering)."""
    matrix = model.transition_matrix
    n = model.nr_states
    data, columns, indptr = [], [], [0]
    for row in range(matrix.nr_rows):
        for entry in matrix.get_row(row):
            columns.append(entry.column)
            data.append(float(entry.value))
        indptr.append(len(columns))
    transitions = sp.csr_matrix((data, columns, indptr), shape=(matrix.nr_rows, n))
    groups = np.array([matrix.get_row_group_start(s) for s in range(n)] + [matrix.nr_rows])
    labels = {}
    for name in model.labeling.get_labels():
        mask = np.zeros(n, dtype=bool)
        mask[list(model.labeling.get_states(name))] = True
        labels[name] = mask
    actions, choice_actions = _actions(model)
    rewards = tuple(_rewards(name, structure, n, matrix.nr_rows)
                    for name, structure in model.reward_models.items())
    return MDP(transitions, groups, np.array(list(model.initial_states)), labels,
               choice_actions, actions, rewards)


def _actions(model: Any) -> tuple[tuple[str, ...], np.ndarray]:
    names = [""]
    per_choice = np.zeros(model.nr_choices, dtype=np.int64)
    if not model.has_choice_labeling():
        return tuple(names), per_choice
    for choice in range(model.nr_choices):
        label = "+".join(sorted(model.choice_labeling.get_labels_of_choice(choice)))
        if label not in names:
            names.append(label)
        per_choice[choice] = names.index(label)
    return tuple(names), per_choice


def _rewards(name: str, structure: Any, states: int, choices: int) -> MdpRewards:
    state = (np.array(list(structure.state_rewards), dtype=float)
             if structure.has_state_rewards else np.zeros(states))
    choice = (np.array(list(structure.state_action_rewards), dtype=float)
              if structure.has_state_action_rewards else np.zeros(choices))
    assert not structure.has_transition_rewards
    return MdpRewards(name, state, choice)


def storm_number(value: Any) -> Fraction | float:
    """A Storm number as an exact Fraction (or ``inf``)."""
    if isinstance(value, int | float):
        return math.inf if math.isinf(value) else Fraction(value)
    text = str(value).strip().lower()
    if text in ("inf", "infinity", "+inf"):
        return math.inf
    return Fraction(text)


def storm_values(built: Built, formula: str, *, exact: bool = True) -> list[Fraction | float]:
    """Storm's value of *formula* in every state (exact engine by default)."""
    model = built.exact if exact else built.floating
    prop = stormpy.parse_properties(formula, built.program)[0]
    result = stormpy.model_checking(model, prop)
    return [storm_number(v) for v in result.get_value_vector()]


# ---------------------------------------------------------------------------
# Random PRISM mdp texts
# ---------------------------------------------------------------------------

DYADIC = ([1], [1, 1], [1, 3], [1, 1, 2], [3, 5], [1, 2, 5])
GENERAL = ([1, 2], [1, 9], [2, 3, 5], [1, 1, 1])
ACTIONS = ("", "", "a", "b", "c")


def random_model(rng: random.Random, *, dyadic: bool = True, modules: int = 2) -> str:
    """A small random PRISM ``mdp``: modules with nondeterministic and synchronised
    commands, a reward structure ``"r"`` with state and action rewards (many zero,
    for zero-reward end components), and labels ``"goal"`` and ``"safe"``."""
    ranges = [rng.randint(1, 3) for _ in range(modules)]
    lines = ["mdp", ""]
    used = {""}
    for i, top in enumerate(ranges):
        lines += [f"module m{i}", f"  x{i} : [0..{top}] init 0;"]
        for _ in range(rng.randint(3, 5)):
            action = rng.choice(ACTIONS)
            used.add(action)
            lines.append(_command(rng, i, ranges, dyadic, action))
        lines += ["endmodule", ""]
    lines += ['rewards "r"']
    for _ in range(rng.randint(1, 3)):
        value = rng.choice(["0", "1", "2", "0.5"])
        action = rng.choice(["", *(f"[{a}] " for a in sorted(used))])
        lines.append(f"  {action}{_guard(rng, ranges)} : {value};")
    lines += ["endrewards", ""]
    lines.append(f'label "goal" = {_atom(rng, ranges)};')
    lines.append(f'label "safe" = {_guard(rng, ranges)};')
    return "\n".join(lines) + "\n"


def _command(rng: random.Random, i: int, ranges: list[int], dyadic: bool, action: str) -> str:
    weights = rng.choice(DYADIC if dyadic else GENERAL)
    total = sum(weights)
    branches = []
    for w in weights:
        branches.append(f"{Fraction(w, total)}:(x{i}'={_next(rng, i, ranges[i])})")
    return f"  [{action}] {_guard(rng, ranges, i)} -> {' + '.join(branches)};"


def _next(rng: random.Random, i: int, top: int) -> str:
    kind = rng.random()
    if kind < 0.4:
        return f"min(x{i}+1,{top})"
    if kind < 0.6:
        return f"max(x{i}-1,0)"
    return str(rng.randint(0, top))


def _guard(rng: random.Random, ranges: list[int], own: int | None = None) -> str:
    if rng.random() < 0.25:
        return "true"
    return " & ".join(_atom(rng, ranges, own) for _ in range(rng.randint(1, 2)))


def _atom(rng: random.Random, ranges: list[int], own: int | None = None) -> str:
    j = own if own is not None and rng.random() < 0.7 else rng.randrange(len(ranges))
    op = rng.choice(["=", "<", ">=", "!="])
    return f"x{j}{op}{rng.randint(0, ranges[j])}"


def exact_entries(built: Built) -> np.ndarray:
    """Storm's rational probabilities of :attr:`Built.mdp`'s stored entries (``mpq``)."""
    from gmpy2 import mpq

    matrix = built.exact.transition_matrix
    values = [mpq(str(entry.value)) for row in range(matrix.nr_rows)
              for entry in matrix.get_row(row)]
    return np.array(values, dtype=object)


def exact_rewards(built: Built, name: str = "r") -> np.ndarray:
    """Storm's rational rewards per choice (state reward plus action reward), ``mpq``."""
    from gmpy2 import mpq

    structure = built.exact.reward_models[name]
    owner = built.mdp.choice_owner
    state = ([mpq(str(v)) for v in structure.state_rewards] if structure.has_state_rewards
             else [mpq(0)] * built.mdp.num_states)
    action = ([mpq(str(v)) for v in structure.state_action_rewards]
              if structure.has_state_action_rewards else [mpq(0)] * built.mdp.num_choices)
    return np.array([state[owner[c]] + action[c] for c in range(owner.size)], dtype=object)
