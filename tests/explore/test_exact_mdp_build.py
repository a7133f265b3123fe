"""The exact MDP build places each choice's rational probabilities and its action's
rewards in the float build's rows: synchronised combinations (some disabled), a lone
command, and a deadlock's self-loop, by hand."""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from veribattery.explore.build.mdp import build_mdp
from veribattery.explore.exact.mdp import build_exact_mdp
from veribattery.lang import flatten_model, parse_model

#: In s=0 both modules synchronise on [a] (2 x 2 commands, one of which is disabled
#: there: 3 combinations) and m1 has a lone [b]; s=1 has only [a] with m2's first
#: command; s=2 has no enabled command (a deadlock).
MODEL = """mdp
module m1
  s : [0..2] init 0;
  [a] s=0 -> 1/3 : (s'=1) + 2/3 : (s'=0);
  [a] s<2 -> (s'=2);
  [b] s=0 -> 1/4 : (s'=2) + 3/4 : (s'=1);
endmodule
module m2
  t : [0..1] init 0;
  [a] true -> 1/2 : (t'=1) + 1/2 : (t'=0);
  [a] t=0 & s=0 -> (t'=0);
endmodule
rewards "cost"
  [a] true : 3;
  [b] true : 5;
  s=2 : 7;
endrewards
"""


def _rows(mdp: object, values: np.ndarray) -> list[list[tuple[int, Fraction]]]:
    """Each choice's (target, probability) entries."""
    matrix = mdp.transitions  # type: ignore[attr-defined]
    return [[(int(matrix.indices[k]), Fraction(values[k]))
             for k in range(matrix.indptr[r], matrix.indptr[r + 1])]
            for r in range(matrix.shape[0])]


def test_exact_rows_are_the_float_rows_in_rationals() -> None:
    model = parse_model(MODEL)
    flat = flatten_model(model, {})
    floats = build_mdp(flat)
    exact = build_exact_mdp(model, flat)
    built = exact.built
    assert np.array_equal(built.row_groups, floats.row_groups)
    assert np.array_equal(built.transitions.indices, floats.transitions.indices)
    assert np.array_equal(built.choice_actions, floats.choice_actions)
    found = _rows(built, exact.probabilities)
    # Every probability here is a binary fraction or a third: the doubles within 1e-15.
    for row, float_row in zip(found, _rows(floats, floats.transitions.data), strict=True):
        assert [t for t, _ in row] == [t for t, _ in float_row]
        assert all(abs(p - q) < 1e-15 for (_, p), (_, q) in zip(row, float_row, strict=True))
    names = [tuple(int(v) for v in state) for state in built.states]
    # The choices of (s=0, t=0): [a] 1x1, 1x2, 2x1, 2x2 and [b], by hand.
    first = names.index((0, 0))
    start, stop = int(built.row_groups[first]), int(built.row_groups[first + 1])
    assert stop - start == 5
    by_state = {names[t]: p for t, p in found[start]}
    assert by_state == {(1, 1): Fraction(1, 6), (1, 0): Fraction(1, 6),
                        (0, 1): Fraction(1, 3), (0, 0): Fraction(1, 3)}
    # The deadlock (s=2) keeps its self-loop, with no action.
    for state, name in enumerate(names):
        if name[0] == 2:
            row = int(built.row_groups[state])
            assert built.row_groups[state + 1] - row == 1
            assert found[row] == [(state, Fraction(1))]
    # Rewards by action: [a] 3 and [b] 5 on the choices, 7 in the deadlock's states.
    cost = exact.reward("cost")
    actions = [floats.actions[k] for k in floats.choice_actions]
    assert [Fraction(c) for c in cost.choice] == [
        {"a": 3, "b": 5, "": 0}[a] for a in actions]
    assert [Fraction(c) for c in cost.state] == [7 if n[0] == 2 else 0 for n in names]
