"""The qualitative pre-computations and the end-component decomposition."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker.mdp.models import TIED_EXIT, mask, mdp_from
from veribattery.checker.mdp import MDP
from veribattery.checker.mdp.components import end_components
from veribattery.checker.mdp.graph import (
    ChoiceGraph,
    almost_surely,
    distinct,
    forced_into,
    prob0a,
    prob0e,
    prob1a,
    prob1e,
)

# 0: a -> 1, b -> 0.5 goal 3 + 0.5 trap 4; 1: c -> 0, d -> 2; 2: -> goal (1/2) or 1 (1/2);
# 3 goal, 4 trap, 5: unreachable from everything, moves to the trap.
GAME = mdp_from([
    [[(1, 1)], [(3, 0.5), (4, 0.5)]],
    [[(0, 1)], [(2, 1)]],
    [[(3, 0.5), (1, 0.5)]],
    [[(3, 1)]],
    [[(4, 1)]],
    [[(4, 1)]],
])


def _graph(mdp: MDP) -> ChoiceGraph:
    return ChoiceGraph.of(mdp.transitions, mdp.choice_owner)


def test_the_four_sets() -> None:
    graph, everywhere, goal = _graph(GAME), np.ones(6, dtype=bool), mask(6, [3])
    assert np.flatnonzero(prob0a(graph, everywhere, goal)).tolist() == [4, 5]
    # 0 and 1 can swap forever: Pmin = 0 there; 2 may be sent back but not held.
    assert np.flatnonzero(prob0e(graph, everywhere, goal)).tolist() == [0, 1, 4, 5]
    assert np.flatnonzero(prob1a(graph, everywhere, goal,
                                 prob0e(graph, everywhere, goal))).tolist() == [3]
    # Pmax = 1 from 0, 1, 2: 0 -> 1 -> 2 -> goal, retrying 2 <-> 1.
    assert np.flatnonzero(prob1e(graph, everywhere, goal)).tolist() == [0, 1, 2, 3]


def test_almost_sure_witnesses_never_risk_the_trap() -> None:
    graph, goal = _graph(GAME), mask(6, [3])
    sure, via = almost_surely(graph, np.ones(6, dtype=bool), goal)
    assert np.flatnonzero(sure).tolist() == [0, 1, 2, 3]
    assert via[[0, 1, 2]].tolist() == [0, 3, 4]  # 0 -a-> 1 -d-> 2 -> ...


def test_forced_into_counts_every_choice() -> None:
    graph = _graph(GAME)
    forced = forced_into(graph, np.ones(6, dtype=bool), mask(6, [3]))
    assert np.flatnonzero(forced).tolist() == [2, 3]  # 0 and 1 may swap


def test_remain_restricts_paths() -> None:
    graph, goal = _graph(GAME), mask(6, [3])
    remain = mask(6, [0, 1])  # 2 may not be passed through
    assert np.flatnonzero(prob1e(graph, remain, goal)).tolist() == [3]
    assert np.flatnonzero(prob0a(graph, remain, goal)).tolist() == [2, 4, 5]


def test_end_components() -> None:
    found = end_components(_graph(GAME), np.ones(6, dtype=bool))
    # {0, 1} (with a and c), {3}, {4}; 2 always risks leaving to the goal, 5 leaves.
    assert found.count == 3
    assert found.component[[2, 5]].tolist() == [-1, -1]
    assert found.component[0] == found.component[1] != found.component[3]
    assert found.inside.tolist() == [True, False, True, False, False, True, True, False]


def test_end_components_restricted() -> None:
    graph = _graph(TIED_EXIT)
    found = end_components(graph, mask(4, [0, 1]), None)
    assert found.count == 1 and found.component.tolist() == [0, 0, -1, -1]
    assert found.inside.tolist() == [True, False, True, False, False, False]
    # Without the choice 1 -> 0 no end component is left among {0, 1}.
    without = end_components(graph, mask(4, [0, 1]), np.array([1, 1, 0, 1, 1, 1], dtype=bool))
    assert without.count == 0


def test_model_validation() -> None:
    P = sp.csr_matrix(np.array([[1.0, 0.0], [0.0, 1.0]]))
    with pytest.raises(ValueError, match="at least one choice"):
        MDP(P, np.array([0, 2, 2]), np.array([0]))
    with pytest.raises(ValueError, match="row_groups"):
        MDP(P, np.array([0, 1]), np.array([0]))
    bad = sp.csr_matrix(np.array([[1.0, 0.0], [0.0, 0.0]]))
    with pytest.raises(ValueError, match="positive probability"):
        MDP(bad, np.array([0, 1, 2]), np.array([0]))
    good = MDP(P, np.array([0, 1, 2]), np.array([0]))
    assert (good.num_states, good.num_choices, good.num_transitions) == (2, 2, 2)
    assert good.choice_owner.tolist() == [0, 1] and good.action_of(1) == ""


@pytest.mark.parametrize("size", [0, 1, 2, 50, 5000])
def test_distinct_is_numpys_unique(size: int) -> None:
    values = np.random.default_rng(size).integers(0, max(size // 3, 1), size=size)
    assert distinct(values).tolist() == sorted(set(values.tolist()))
    assert distinct(values).dtype == np.int64
