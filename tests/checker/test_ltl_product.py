"""The product of a model with an automaton, against a search written out pair by pair.

On random MDPs (a few choices per state) and automata of random formulas, the product's
states must be exactly the pairs a plain breadth-first search over (state, automaton
state) reaches from the starts, each with the model's choices and probabilities moved to
the pairs they enter, and every model state's start the pair the search began with.
"""

from __future__ import annotations

import random
from collections import deque

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker.automata.oracle import random_formula
from veribattery.checker.automata import parity_automaton
from veribattery.checker.ltl.product import product


def _random_mdp(rng: random.Random, n: int) -> tuple[sp.csr_matrix, np.ndarray]:
    rows, groups = [], [0]
    for _ in range(n):
        for _ in range(rng.randint(1, 2)):
            targets = rng.sample(range(n), rng.randint(1, 3))
            weights = [rng.randint(1, 4) for _ in targets]
            rows.append({t: w / sum(weights) for t, w in zip(targets, weights, strict=True)})
        groups.append(len(rows))
    data, indices, indptr = [], [], [0]
    for row in rows:
        for t in sorted(row):
            indices.append(t)
            data.append(row[t])
        indptr.append(len(indices))
    matrix = sp.csr_matrix((data, indices, indptr), shape=(len(rows), n))
    return matrix, np.array(groups, dtype=np.int64)


@pytest.mark.parametrize("seed", range(40))
def test_the_product_is_the_pairs_a_search_reaches(seed: int) -> None:
    rng = random.Random(seed)
    n = rng.randint(3, 9)
    transitions, groups = _random_mdp(rng, n)
    automaton = parity_automaton(random_formula(rng, 2, 3), 2)
    column = np.array([rng.randrange(4) for _ in range(n)])  # each state's letter
    successor = automaton.successor
    start = {s: (s, int(successor[automaton.initial, column[s]])) for s in range(n)}
    seen, queue = set(start.values()), deque(start.values())
    while queue:
        s, q = queue.popleft()
        for t in transitions[groups[s]:groups[s + 1]].indices:
            pair = (int(t), int(successor[q, column[t]]))
            if pair not in seen:
                seen.add(pair)
                queue.append(pair)

    joint = product(transitions, groups, automaton, column)

    pairs = list(zip(joint.model_state.tolist(), joint.automaton_state.tolist(), strict=True))
    assert sorted(pairs) == sorted(seen)
    assert [pairs[joint.start[s]] for s in range(n)] == [start[s] for s in range(n)]
    for index, (s, q) in enumerate(pairs):
        mine = joint.transitions[joint.row_groups[index]:joint.row_groups[index + 1]]
        theirs = transitions[groups[s]:groups[s + 1]]
        assert mine.shape[0] == theirs.shape[0]
        for c in range(theirs.shape[0]):
            want = {(int(t), int(successor[q, column[t]])): p
                    for t, p in zip(theirs[c].indices, theirs[c].data, strict=True)}
            got = {pairs[j]: p for j, p in zip(mine[c].indices, mine[c].data, strict=True)}
            assert got == want
            assert list(mine[c].indices) == sorted(mine[c].indices)  # rows stay sorted
