"""The remembering Bellman image gives the same floats as computing every row afresh."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.checker.mdp.models import mdp_from
from veribattery.checker.mdp.image import BellmanImage
from veribattery.checker.mdp.system import (
    ChoiceSystem,
    Objective,
    equations,
    quotient_classes,
)


def _random_system(rng: np.random.Generator, n: int,
                   most_choices: int = 3) -> tuple[ChoiceSystem, np.ndarray]:
    """States 0..n-1 unknown, two known states after them (values 0 and 1); each unknown
    state has one to *most_choices* choices of one to four successors with random weights, the
    first of which reaches a known state (so that the first choices' system is
    nonsingular)."""
    states = []
    for _ in range(n):
        state = []
        for i in range(int(rng.integers(1, most_choices + 1))):
            drawn = rng.integers(0, n + 2, size=int(rng.integers(1, 5))).tolist()
            if i == 0:
                drawn.append(n + int(rng.integers(0, 2)))
            successors = sorted(set(drawn))
            weights = rng.random(len(successors)) + 0.1
            state.append([(t, float(w)) for t, w in zip(successors, weights / weights.sum(),
                                                        strict=True)])
        states.append(state)
    states += [[[(n, 1.0)]], [[(n + 1, 1.0)]]]
    mdp = mdp_from(states)
    unknown = np.zeros(n + 2, dtype=bool)
    unknown[:n] = True
    system = equations(mdp.transitions, mdp.choice_owner, quotient_classes(unknown))
    known = np.array([0.0, 1.0])[system.known_states - n]
    return system, known


@pytest.mark.parametrize("objective", ["max", "min"])
@pytest.mark.parametrize("up", [True, False])
@pytest.mark.parametrize("seed", range(5))
def test_remembered_images_are_the_fresh_ones(monkeypatch: pytest.MonkeyPatch, seed: int,
                                              up: bool, objective: Objective) -> None:
    rng = np.random.default_rng(seed)
    system, known = _random_system(rng, 300)
    partial = []
    original = ChoiceSystem.extended_bound_images

    def spying(self: ChoiceSystem, *args: Any, **kwargs: Any) -> Any:
        partial.append(kwargs.get("rows") is not None)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(ChoiceSystem, "extended_bound_images", spying)
    image = BellmanImage(system, known, None, objective, up=up)
    x = rng.random(system.size)
    before_last = x.copy()
    for step in range(12):
        got = image(x)
        x_before = x.copy()
        fresh = BellmanImage(system, known, None, objective, up=up)(x)
        assert got.view(np.int64).tolist() == fresh.view(np.int64).tolist()
        # The next argument differs in a few entries (some set to 0, as a bound at
        # its floor), changed in place as the certificate does: the image recomputes
        # only the rows that read them.
        if step % 3 == 2:  # back to the argument before last: no stale row may stay
            x[:] = before_last
        else:
            at = rng.choice(system.size, 4, replace=False)
            x[at] = np.where(rng.random(4) < 0.25, 0.0, x[at] * (1 + rng.random(4) * 1e-3))
        before_last = x_before
        assert x_before.tolist() != x.tolist()
        got[:] = -1.0  # a caller's changes to its image must not reach the memory
    assert sum(partial) >= 10


@pytest.mark.parametrize("objective", ["max", "min"])
@pytest.mark.parametrize("up", [True, False])
@pytest.mark.parametrize("most_choices", [1, 3, 20])
@pytest.mark.parametrize("rewarded", [False, True])
def test_image_is_the_best_row_bound(up: bool, objective: Objective, most_choices: int,
                                     rewarded: bool) -> None:
    rng = np.random.default_rng(most_choices)
    system, known = _random_system(rng, 300, most_choices)
    offset = None
    if rewarded:  # rewards on half the rows: rows reading only zeros come alive
        offset = np.where(rng.random(system.choices.size) < 0.5, rng.random(system.choices.size),
                          0.0)
    image = BellmanImage(system, known, offset, objective, up=up)
    for _ in range(3):  # the last live rows kept, then made again for other zeros
        x = rng.random(system.size)
        x[rng.random(system.size) < 0.6] = 0.0
        x[:3] = np.inf if up else 0.0
        expected = system.best(system.bound_images(x, known, offset, up=up), objective)
        image(x * (1 + rng.random(system.size)))  # every entry moves, the zeros stay
        got = image(x)
        assert got.view(np.int64).tolist() == expected.view(np.int64).tolist()
