"""Storm (stormpy) as the strategy source of the synthesis tests: build the mission MDP,
take a memoryless scheduler, follow it from the initial state, and hand the states it
reaches to the threshold table as (valuation, action).

The model is read out of Storm once, into arrays (its transitions row by row, each
row's action, each state's variables), so that following a strategy and valuing
choices need no per-state calls into Storm.

Import this module only after ``pytest.importorskip("stormpy")``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import scipy.sparse as sp
import stormpy
from scipy.sparse.csgraph import breadth_first_order

from tests.render.spec_mdp import Choice, State
from veribattery.synthesis.decisions import GO_ON
from veribattery.synthesis.strategy import STATE_VARIABLES, strategy_frame

GO_ON_ACTIONS = frozenset(GO_ON.values())


@dataclass(frozen=True)
class StormMdp:
    """Storm's model of a PRISM MDP (or DTMC: one row per state), read into arrays.

    :ivar groups: the first row of each state, and the number of rows at the end.
    :ivar matrix: the rows (choices) as a CSR matrix over states.
    :ivar labels: each row's action label ("" for an unlabelled loop).
    :ivar variables: each state variable's value per state (a constant wind: 0).
    """

    model: Any
    program: Any
    groups: np.ndarray
    matrix: sp.csr_matrix
    labels: np.ndarray
    variables: dict[str, np.ndarray]

    @classmethod
    def build(cls, text: str, folder: Path, name: str = "model.prism") -> StormMdp:
        """Storm's full model of the PRISM *text*: state valuations, choice labels and
        every reward model."""
        path = folder / name
        path.write_text(text)
        program = stormpy.parse_prism_program(str(path))
        options = stormpy.BuilderOptions()
        options.set_build_state_valuations()
        options.set_build_choice_labels()
        options.set_build_all_labels()
        options.set_build_all_reward_models()
        model = stormpy.build_model(program, options=options)
        return cls(model, program, _groups(model), _matrix(model), _labels(model),
                   _variables(model))

    @property
    def initial(self) -> int:
        return int(self.model.initial_states[0])

    def state(self, s: int) -> State:
        return State(*(int(self.variables[v][s]) for v in State._fields))

    def value(self, formula: str, **options: Any) -> Any:
        """Storm's answer to *formula* at the initial state."""
        prop = stormpy.parse_properties(formula, self.program)[0]
        result = stormpy.model_checking(self.model, prop, **options)
        if result.is_qualitative():
            return result.get_truth_values_vector()[self.initial]
        return result.get_value(self.initial)

    def optimal(self, formula: str) -> tuple[np.ndarray, float, np.ndarray]:
        """Storm's optimal memoryless scheduler for *formula* (its row in each state),
        the value at the initial state, and the value of every state."""
        prop = stormpy.parse_properties(formula, self.program)[0]
        result = stormpy.model_checking(self.model, prop, extract_scheduler=True)
        scheduler = result.get_scheduler()
        assert scheduler.memoryless and scheduler.deterministic
        chosen = [scheduler.get_choice(s).get_deterministic_choice()
                  for s in range(self.model.nr_states)]
        rows = self.groups[:-1] + np.asarray(chosen, dtype=np.int64)
        return rows, float(result.get_value(self.initial)), np.asarray(
            result.get_value_vector(), dtype=float)

    def reachable(self, rows: np.ndarray) -> np.ndarray:
        """The states reachable from the initial state when each state takes *rows*."""
        induced = self.matrix[rows]
        order = breadth_first_order(induced, self.initial, directed=True,
                                    return_predecessors=False)
        return np.sort(order)

    def strategy(self, rows: np.ndarray, states: np.ndarray | None = None,
                 indifferent: Sequence[bool] | None = None) -> pd.DataFrame:
        """The strategy frame of *rows* on *states* (default: those it reaches)."""
        states = self.reachable(rows) if states is None else states
        columns = {name: self.variables[name][states] for name in STATE_VARIABLES}
        return strategy_frame(columns, self.labels[rows[states]].tolist(),
                              indifferent=indifferent)

    def choice_values(self, values: np.ndarray) -> np.ndarray:
        """Each row's expected successor value under the state *values*."""
        return np.asarray(self.matrix @ values, dtype=float)


def _groups(model: Any) -> np.ndarray:
    if not model.is_nondeterministic_model:
        return np.arange(model.nr_states + 1, dtype=np.int64)
    return np.asarray(model.nondeterministic_choice_indices, dtype=np.int64)


def _matrix(model: Any) -> sp.csr_matrix:
    matrix = model.transition_matrix
    indptr, columns, probs = [0], [], []
    for r in range(matrix.nr_rows):
        for entry in matrix.get_row(r):
            columns.append(entry.column)
            probs.append(entry.value)
        indptr.append(len(columns))
    return sp.csr_matrix((probs, columns, indptr), shape=(matrix.nr_rows, model.nr_states))


def _labels(model: Any) -> np.ndarray:
    labeling = model.choice_labeling
    labels = np.full(model.transition_matrix.nr_rows, "", dtype=object)
    for label in labeling.get_labels():
        labels[np.fromiter(labeling.get_choices(label), dtype=np.int64)] = label
    return labels


def _variables(model: Any) -> dict[str, np.ndarray]:
    valuations = model.state_valuations
    found = {v.name: np.asarray(valuations.get_int64_values(v), dtype=np.int64)
             for v in valuations.get_all_variables()}
    # A wind that never changes (p_wsp_c = 0) is a constant to Storm, not a variable.
    found.setdefault("wsp", np.zeros(model.nr_states, dtype=np.int64))
    return found


def frame(states: Sequence[State], actions: Sequence[str],
          indifferent: Sequence[bool] | None = None) -> pd.DataFrame:
    """The strategy frame of *states* choosing *actions*."""
    columns = {name: [getattr(x, name) for x in states] for name in STATE_VARIABLES}
    return strategy_frame(columns, actions, indifferent=indifferent)


def choice_values(choices: Sequence[Choice], value: dict[State, Fraction],
                  here: State) -> list[Fraction]:
    """Each choice's exact value under *value* (a self-loop solved as in spec_mdp)."""
    out = []
    for _, dist in choices:
        stay = dist.get(here, Fraction(0))
        if stay == 1:
            out.append(value[here])
            continue
        out.append(sum((p * value[y] for y, p in dist.items() if y != here), Fraction(0))
                   / (1 - stay))
    return out


def indifference(model: dict[State, list[Choice]],
                 value: dict[State, Fraction]) -> Callable[[State], bool]:
    """Whether going on and turning back are exactly equally good at a state of *model*
    (both possible, and the best of turning back -- return or abort -- worth as much as
    going on), by the exact values *value*."""
    def indifferent(x: State) -> bool:
        worth = dict(zip([a for a, _ in model[x]], choice_values(model[x], value, x),
                         strict=True))
        go_on = [v for a, v in worth.items() if a in GO_ON_ACTIONS]
        back = [v for a, v in worth.items() if a not in GO_ON_ACTIONS]
        return bool(go_on and back) and go_on[0] == max(back)
    return indifferent


def exactly_optimal(model: dict[State, list[Choice]], value: dict[State, Fraction],
                    x: State, chosen: str) -> bool:
    """Whether *chosen* is worth *value* at *x* (an optimal choice), exactly."""
    worth = dict(zip([a for a, _ in model[x]], choice_values(model[x], value, x), strict=True))
    return worth[chosen] == value[x]
