"""LTL (negation normal form) to a transition-based Büchi automaton, by a tableau.

A state of the generalised automaton is a set of formulas that must hold at the current
position (initially ``{f}``). Reading a letter, the set is expanded as in the tableau of
Gerth, Peled, Vardi and Wolper (PSTV 1995), in the transition-based form of Couvreur
(FM 1999): literals are checked against the letter, ``a & b`` asserts both, ``a | b``
branches, ``X a`` puts ``a`` into the successor's set, ``a U b`` branches into ``b`` or
``a, X(a U b)``, and ``a R b`` into ``a, b`` or ``b, X(a R b)``. Each branch that does
not meet a contradiction is a transition to the set of its X-obligations. The
transition is in the acceptance set of an until ``a U b`` unless the branch asserted
``a U b`` without asserting ``b``: a run that postpones an until forever is in that set
only finitely often, and the canonical run of a model (fulfilling ``b`` as soon as it
holds) is in every set infinitely often.

A branch whose obligations include another's and whose acceptance sets are among the
other's is dropped (the other one accepts the same suffixes at least as well; this is
the usual pruning of Couvreur's and Spot's translators). The acceptance sets, one per
until, are then merged into one by the counter construction (degeneralisation): the
state carries the index of the set awaited next, and the transition that passes the
last one is accepting. Finally bisimilar states are merged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from veribattery.checker.automata._limit import check_size
from veribattery.checker.automata.formula import (
    And,
    Const,
    LtlFormula,
    Next,
    Not,
    Or,
    Prop,
    Release,
    Until,
)

# Kinds of the interned formula nodes (the formula is in negation normal form).
_TRUE, _FALSE, _PROP, _NOT_PROP, _AND, _OR, _NEXT, _UNTIL, _RELEASE = range(9)

#: A transition: target state and whether it is accepting.
Edge = tuple[int, bool]


@dataclass(frozen=True)
class Buchi:
    """A transition-based Büchi automaton over the letters ``0 .. 2**k - 1``.

    ``edges[state][letter]`` lists the transitions; a run is accepting iff it takes an
    accepting transition infinitely often. States may have no transition on a letter.
    """

    initial: int
    edges: list[list[tuple[Edge, ...]]]


class _Closure:
    """The subformulas of one formula, interned as integers with their kind and operands.

    Sets of small integers make the tableau's states cheap to hash and compare.
    """

    def __init__(self) -> None:
        self.kind: list[int] = []
        self.left: list[int] = []
        self.right: list[int] = []
        self._ids: dict[tuple[int, int, int], int] = {}

    def intern(self, f: LtlFormula) -> int:
        match f:
            case Const(value):
                return self._node(_TRUE if value else _FALSE, -1, -1)
            case Prop(index):
                return self._node(_PROP, index, -1)
            case Not(Prop(index)):
                return self._node(_NOT_PROP, index, -1)
            case Next(operand):
                return self._node(_NEXT, self.intern(operand), -1)
            case And(a, b) | Or(a, b) | Until(a, b) | Release(a, b):
                kind = {And: _AND, Or: _OR, Until: _UNTIL, Release: _RELEASE}[type(f)]
                return self._node(kind, self.intern(a), self.intern(b))
        raise ValueError(f"not in negation normal form: {f!r}")

    def _node(self, kind: int, left: int, right: int) -> int:
        key = (kind, left, right)
        if key not in self._ids:
            self._ids[key] = len(self.kind)
            self.kind.append(kind)
            self.left.append(left)
            self.right.append(right)
        return self._ids[key]

    def untils(self) -> list[int]:
        return [i for i, kind in enumerate(self.kind) if kind == _UNTIL]


def _branches(c: _Closure, state: frozenset[int],
              letter: int) -> list[tuple[frozenset[int], frozenset[int]]]:
    """The consistent expansions of ``state`` under ``letter``: (asserted, obligations)."""
    found = []
    stack: list[tuple[list[int], set[int], set[int]]] = [(list(state), set(), set())]
    while stack:
        todo, done, nxt = stack.pop()
        alive = True
        while todo and alive:
            f = todo.pop()
            if f in done:
                continue
            done.add(f)
            kind, a, b = c.kind[f], c.left[f], c.right[f]
            if kind == _FALSE:
                alive = False
            elif kind == _PROP:
                alive = bool(letter >> a & 1)
            elif kind == _NOT_PROP:
                alive = not letter >> a & 1
            elif kind == _AND:
                todo += (a, b)
            elif kind == _NEXT:
                nxt.add(a)
            elif kind == _OR and a not in done and b not in done:
                stack.append(([*todo, b], set(done), set(nxt)))
                todo.append(a)
            elif kind == _UNTIL and b not in done:
                stack.append(([*todo, a], set(done), {*nxt, f}))
                todo.append(b)
            elif kind == _RELEASE and not (a in done and b in done):
                stack.append(([*todo, b], set(done), {*nxt, f}))
                todo += (a, b)
        if alive:
            found.append((frozenset(done), frozenset(nxt)))
    return found


def _transitions(c: _Closure, untils: list[int], state: frozenset[int],
                 letter: int) -> list[tuple[frozenset[int], frozenset[int]]]:
    """The undominated transitions of ``state`` on ``letter``: (successor, acceptance)."""
    options = set()
    for done, nxt in _branches(c, state, letter):
        accepted = frozenset(u for u in untils if u not in done or c.right[u] in done)
        options.add((nxt, accepted))
    return [(nxt, acc) for nxt, acc in options
            if not any(other != (nxt, acc) and other[0] <= nxt and other[1] >= acc
                       for other in options)]


def buchi_automaton(f: LtlFormula, alphabet: Sequence[int], max_states: int) -> Buchi:
    """The transition-based Büchi automaton of ``f`` (in negation normal form), its edges
    of each state listed per letter of *alphabet*, in order."""
    closure = _Closure()
    start = frozenset({closure.intern(f)})
    untils = closure.untils()
    levels = len(untils)
    # Generalised states are discovered breadth-first; the degeneralised state
    # (set, level) is numbered on first sight.
    index: dict[tuple[frozenset[int], int], int] = {(start, 0): 0}
    order = [(start, 0)]
    edges: list[list[tuple[Edge, ...]]] = []
    cache: dict[frozenset[int], list[list[tuple[frozenset[int], frozenset[int]]]]] = {}
    while len(edges) < len(order):
        state, level = order[len(edges)]
        if state not in cache:
            cache[state] = [_transitions(closure, untils, state, letter)
                            for letter in alphabet]
        row = []
        for options in cache[state]:
            out = []
            for nxt, acc in options:
                reached = level
                while reached < levels and untils[reached] in acc:
                    reached += 1
                accepting = reached == levels
                target = (nxt, 0 if accepting else reached)
                if target not in index:
                    index[target] = len(order)
                    order.append(target)
                    check_size(len(order), max_states, "Büchi automaton of the formula")
                out.append((index[target], accepting))
            row.append(tuple(sorted(out)))
        edges.append(row)
    return _quotient(Buchi(0, edges))


def _quotient(buchi: Buchi) -> Buchi:
    """The quotient by the coarsest bisimulation that respects accepting transitions.

    Bisimilar states have the same runs up to the classes, with the same accepting
    transitions, hence the same language; the tableau's syntactically different sets
    are often bisimilar, and determinisation is exponential in the number of states.
    """
    classes = [0] * len(buchi.edges)
    count = 1
    while True:
        signatures: dict[tuple[object, ...], int] = {}
        refined = []
        for state, row in enumerate(buchi.edges):
            moves = tuple(frozenset((classes[t], a) for t, a in options) for options in row)
            refined.append(signatures.setdefault((classes[state], moves), len(signatures)))
        classes = refined
        if len(signatures) == count:
            break
        count = len(signatures)
    edges: list[list[tuple[Edge, ...]]] = [[] for _ in range(count)]
    done = [False] * count
    for state, row in enumerate(buchi.edges):
        if not done[classes[state]]:
            done[classes[state]] = True
            edges[classes[state]] = [tuple(sorted({(classes[t], a) for t, a in options}))
                                     for options in row]
    return Buchi(classes[buchi.initial], edges)
