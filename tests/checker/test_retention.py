"""What a checked property keeps alive after its check (memory), values unchanged.

A run of several properties reduces each result to its answer when asked
(``keep="answers"``, what the CLI does), the kernels' memo frees the previous
linear system before building the next, and a triangular plan (index work by
sparsity pattern, for sweeps) is kept only for a pattern seen a second time.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp

from tests.checker.chains import dtmc, mask, matrix
from veribattery.checker import Workspace, check, kernels, linalg
from veribattery.checker.kernels import prepass
from veribattery.checker.linalg import triangular
from veribattery.lang import parse_property
from veribattery.pipeline import check_prism_file

# Gambler's ruin on 0..4 with p = 1/4 up, plus a reward per step.
RUIN = """dtmc
module m
  x : [0..4] init 2;
  [] x>0 & x<4 -> 0.25:(x'=x+1) + 0.75:(x'=x-1);
endmodule
label "win" = x=4;
label "end" = x=0 | x=4;
rewards "steps" x>0 & x<4 : 1; endrewards
"""
PROPS = 'P=? [ F "win" ];\nR{"steps"}=? [ F "end" ];\nP>=0.5 [ F "win" ];\n'


def _ruin_win(start: int) -> Fraction:
    """P(reach 4 before 0) from *start*: (r^start - 1) / (r^4 - 1), r = q/p = 3."""
    return Fraction(3**start - 1, 3**4 - 1)


def test_without_states_keeps_the_answer_and_drops_the_vectors() -> None:
    chain = dtmc({0: {1: 0.5, 2: 0.5}, 1: {1: 1.0}, 2: {0: 0.5, 3: 0.5}}, 4,
                 labels={"goal": [3]})
    full = check(chain, parse_property('P=? [ F "goal" ]'))
    small = full.without_states()
    # x0 = 1/2 x2, x2 = 1/2 x0 + 1/2  =>  x0 = 1/3
    assert full.values.shape == (4,) and full.bounds is not None
    assert full.lower is not None and full.upper is not None
    assert full.lower <= 1 / 3 <= full.upper
    assert small.values.shape == (0,) and small.values.dtype == np.float64
    assert small.bounds is None
    assert (small.value, small.lower, small.upper, small.precise) == (
        full.value, full.lower, full.upper, full.precise)
    assert small.without_states() is small


def test_runs_without_states_give_the_same_answers(tmp_path: object) -> None:
    kept = check_prism_file(RUIN, props_source=PROPS)
    answers = check_prism_file(RUIN, props_source=PROPS, keep="answers")
    assert [r.value for r in answers.results] == [r.value for r in kept.results]
    assert [(r.lower, r.upper) for r in answers.results] == [
        (r.lower, r.upper) for r in kept.results]
    assert all(r.values.size == 0 and r.bounds is None for r in answers.results)
    assert kept.results[0].values.size == 5
    win = float(_ruin_win(2))
    assert answers.results[0].value == pytest.approx(win, rel=1e-12)
    assert answers.results[2].value is False  # 1/10 < 0.5


def test_the_old_system_is_freed_before_the_next_is_built(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    P = matrix({0: {1: 0.5, 2: 0.5}, 1: {0: 0.5, 3: 0.5}, 2: {1: 0.5, 4: 0.5}}, 5)
    alive: list[int] = []
    restrict = linalg.restricted_parts
    workspace = Workspace()

    def spy(P: sp.csr_matrix, maybe: np.ndarray, plans: linalg.SolverPlans) -> object:
        alive.append(len(workspace.kernels.of(P).systems))
        return restrict(P, maybe, plans)

    monkeypatch.setattr(linalg, "restricted_parts", spy)
    everywhere = np.ones(5, dtype=bool)
    first = kernels.until_probs(P, everywhere, mask(5, [3]), workspace=workspace)
    second = kernels.until_probs(P, ~mask(5, [2]), mask(5, [3]),
                                 workspace=workspace)  # unknowns {0, 1} only
    assert alive == [0, 0]  # with SYSTEMS_KEPT = 1, none kept while building
    assert len(workspace.kernels.of(P).systems) == 1
    # x0 = (x1 + x2)/2, x1 = x0/2 + 1/2, x2 = x1/2: x0 = 3/5. Not through 2: x0 = x1/2,
    # x1 = x0/2 + 1/2: x0 = 1/3.
    assert first.value[0] == pytest.approx(0.6, rel=1e-15)
    assert second.value[0] == pytest.approx(1 / 3, rel=1e-15)


def test_triangular_plans_are_kept_only_for_patterns_seen_again() -> None:
    A = sp.csr_matrix(np.array([[1.0, 0.0, 0.0], [-0.5, 1.0, 0.0], [0.0, -0.25, 1.0]]))
    plans = linalg.SolverPlans()
    first = triangular._triangular_inverse(A, plans)
    assert first is not None and not plans.triangular and len(plans.triangular_seen) == 1
    B = A.copy()
    B.data = B.data * 0.5  # same pattern, other values
    second = triangular._triangular_inverse(B, plans)
    assert second is not None and len(plans.triangular) == 1 and not plans.triangular_seen
    b = np.array([1.0, 2.0, 3.0])
    assert np.allclose(first(b), np.linalg.solve(A.toarray(), b), rtol=1e-15)
    assert np.allclose(second(b), np.linalg.solve(B.toarray(), b), rtol=1e-15)


def _reach_reference(P: sp.csr_matrix, through: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """Backward search one state at a time over the positive entries."""
    dense = P.toarray()
    reached = seeds.copy()
    changed = True
    while changed:
        changed = False
        for i in range(dense.shape[0]):
            if not reached[i] and through[i] and np.any(reached[dense[i] > 0]):
                reached[i] = changed = True
    return reached


@pytest.mark.parametrize("seed", range(30))
def test_backward_reach_matches_a_plain_search(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 30))
    dense = (rng.random((n, n)) < 0.15) * rng.random((n, n))
    P = sp.csr_matrix(dense)
    if seed % 2:  # stored zeros are not transitions
        P.data[rng.random(P.nnz) < 0.3] = 0.0
    through, seeds = rng.random(n) < 0.7, rng.random(n) < 0.15
    before = P.copy()
    found = prepass._backward_reach(P, through, seeds, Workspace())
    assert np.array_equal(found, _reach_reference(before, through, seeds))
    # the search must leave P as it was, stored zeros included
    assert np.array_equal(P.indptr, before.indptr) and np.array_equal(P.indices, before.indices)
