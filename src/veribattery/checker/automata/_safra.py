"""Büchi to deterministic parity automaton: Safra's trees with Piterman's dynamic names.

A state is a compact Safra tree (Safra, FOCS 1988; Piterman, LMCS 3(3:5), 2007): nodes
named ``1 .. m`` by age (a parent is older than its children, an older sibling than a
younger one), each labelled with a non-empty set of Büchi states; a child's label is a
subset of its parent's, siblings' labels are disjoint, and the children's labels
together cover their parent's strictly. Reading a letter:

1. every node gets a new youngest child labelled with the states its label reaches by an
   accepting transition (the transition-based form of Safra's "copy the accepting
   states into a new child", as in Schewe and Varghese, ATVA 2012), and every old
   label is replaced by its successors;
2. horizontal merge: a state in a node's label and in an older sibling's (or in the
   label of an older sibling of an ancestor) is dropped from the younger node, which
   keeps the labels of siblings disjoint;
3. nodes with an empty label are removed;
4. vertical merge: a node whose label equals the union of its children's labels is
   marked good, and all its descendants are removed;
5. the surviving nodes are renamed ``1 .. m`` in their old order.

With ``e`` the least name removed (in 3 or 4) and ``g`` the least name marked good, the
transition's priority is ``min(2g, 2e - 1)``, or an odd priority above all others if
nothing happened (Piterman's Theorem 3.3 with min-parity). A word is accepted iff some
node is eventually never removed (hence keeps its name) and is marked good infinitely
often, which is Safra's condition for an accepting run of the Büchi automaton.
"""

from __future__ import annotations

from dataclasses import dataclass

from veribattery.checker.automata._limit import check_size
from veribattery.checker.automata._tableau import Buchi

#: A compact Safra tree: (parent name - 1 or -1 for the root, label) per node, by name.
Tree = tuple[tuple[int, frozenset[int]], ...]


@dataclass(frozen=True)
class TransitionParity:
    """A complete deterministic automaton with min-parity priorities on its transitions.

    ``successor[q][letter]`` and ``priority[q][letter]``; state 0 is the initial one.
    """

    successor: list[list[int]]
    priority: list[list[int]]


def _step(buchi: Buchi, tree: Tree, letter: int, idle: int) -> tuple[Tree, int]:
    """The tree after reading ``letter`` and the transition's priority."""
    parents = [parent for parent, _ in tree]
    labels: list[set[int]] = []
    fresh: list[tuple[int, set[int]]] = []
    for name, (_, label) in enumerate(tree):
        reached: set[int] = set()
        accepted: set[int] = set()
        for state in label:
            for target, accepting in buchi.edges[state][letter]:
                reached.add(target)
                if accepting:
                    accepted.add(target)
        labels.append(reached)
        if accepted:
            fresh.append((name, accepted))
    for parent, accepted in fresh:
        parents.append(parent)
        labels.append(accepted)
    # Names grow with age, so one pass in name order visits every parent before its
    # children and every older sibling before the younger ones.
    taken: list[set[int]] = [set() for _ in labels]
    for node, parent in enumerate(parents):
        if parent >= 0:
            labels[node] &= labels[parent]
            labels[node] -= taken[parent]
            taken[parent] |= labels[node]
    alive = [bool(label) for label in labels]
    removed = [node for node, live in enumerate(alive) if not live]
    good = []
    for node in range(len(labels)):
        if alive[node] and taken[node] == labels[node]:
            good.append(node)
            for other in range(node + 1, len(labels)):
                if alive[other] and _below(parents, other, node):
                    removed.append(other)
                    alive[other] = False
    names = {}
    survivors: list[tuple[int, frozenset[int]]] = []
    for node, live in enumerate(alive):
        if live:
            names[node] = len(survivors)
            parent = parents[node]
            survivors.append((names[parent] if parent >= 0 else -1, frozenset(labels[node])))
    priority = idle
    if removed:
        priority = min(priority, 2 * (min(removed) + 1) - 1)
    if good:
        priority = min(priority, 2 * (min(good) + 1))
    return tuple(survivors), priority


def _below(parents: list[int], node: int, ancestor: int) -> bool:
    """Whether ``node`` is a proper descendant of ``ancestor``."""
    parent = parents[node]
    while parent > ancestor:
        parent = parents[parent]
    return parent == ancestor


def determinise(buchi: Buchi, letters: int, max_states: int) -> TransitionParity:
    """The deterministic parity automaton of ``buchi`` (whose edges are listed per letter,
    *letters* of them), reachable trees only."""
    states = len(buchi.edges)
    # At most 2 * states nodes exist within a step, so 4 * states + 1 exceeds any
    # priority of an event; it is odd: a run where nothing happens forever rejects.
    idle = 4 * states + 1
    start: Tree = ((-1, frozenset({buchi.initial})),)
    index: dict[Tree, int] = {start: 0}
    order = [start]
    successor: list[list[int]] = []
    priority: list[list[int]] = []
    while len(successor) < len(order):
        tree = order[len(successor)]
        row_successor, row_priority = [], []
        for letter in range(letters):
            target, value = _step(buchi, tree, letter, idle)
            if target not in index:
                index[target] = len(order)
                order.append(target)
                check_size(len(order), max_states, "deterministic parity automaton")
            row_successor.append(index[target])
            row_priority.append(value)
        successor.append(row_successor)
        priority.append(row_priority)
    return TransitionParity(successor, priority)
