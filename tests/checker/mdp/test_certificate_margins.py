"""The certificate's candidates from more than one margin: where the final strategy's
margin fails the test at factor 2, the margin of the strategy before its ties were
tightened is tried before the wider ladders."""

from __future__ import annotations

import numpy as np

from veribattery.checker.mdp import certificate

N = 20


def _swap(v: np.ndarray) -> np.ndarray:
    """A monotone map with the fixed point 1 everywhere: each state of a ring takes 0.9
    of the next one's value plus 0.1 (rounded up, as a rigorous upper image is)."""
    return np.nextafter(0.9 * np.roll(v, -1) + 0.1, np.inf)


IMAGES = certificate._Images(_swap, _swap, np.zeros(N), np.full(N, 10.0))
X = np.ones(N)
#: Room above one state only: the state before it reads 0.9 of it and fails, and pushing
#: moves the failure one state back a round, more than 2 % of the states for four rounds:
#: every factor fails, and the bound is the trivial one.
LOPSIDED = np.where(np.arange(N) == 0, 1e-3, 0.0)
#: Room above every state: 0.9 of the next one's room fits under one's own.
EVEN = np.full(N, 1e-3)


def test_a_second_margin_passes_where_the_first_fails() -> None:
    tight = X + 2 * EVEN + 1e-12
    alone = certificate._side(_swap, X, (LOPSIDED,), IMAGES, None, up=True)
    assert np.all(_swap(alone) <= alone) and np.any(alone > tight)  # (wider, or trivial)
    both = certificate._side(_swap, X, (LOPSIDED, EVEN), IMAGES, None, up=True)
    assert np.all(_swap(both) <= both)  # (it passes the test: an upper bound)
    assert np.all(both > X) and np.all(both <= tight)  # (the second margin, at factor 2)


def test_the_first_margin_is_kept_where_it_passes() -> None:
    found = certificate._side(_swap, X, (EVEN, 10 * EVEN), IMAGES, None, up=True)
    assert np.all(found <= X + 2 * EVEN + 1e-12)
