"""From transition priorities to state priorities, and a smaller equivalent automaton.

- **State-based priorities**: the state ``(tree, p)`` stands for "in ``tree``, having
  just taken a transition of priority ``p``"; its successor on a letter is the tree's
  successor with that transition's priority. The priorities of the states ``q1, q2,
  ...`` of a run are then exactly those of its transitions, so the minimum seen
  infinitely often, and acceptance, are unchanged.
- **Priority normalisation**: only the parity of the least priority of each cycle
  matters; the least priorities with that property are computed per strongly
  connected component (see :func:`normalise_priorities`).
- **Minimisation**: Moore's partition refinement on (priority, successor classes). States
  in one class have the same priority sequence along every word, hence the same
  language; the quotient is the coarsest such bisimulation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array
from scipy.sparse.csgraph import connected_components

from veribattery.checker.automata._limit import check_size
from veribattery.checker.automata._safra import TransitionParity


def state_based(dpa: TransitionParity, max_states: int) -> tuple[NDArray[np.int32],
                                                                   NDArray[np.int64]]:
    """Successor table and state priorities; state 0 is the initial one."""
    incoming = [p for row_s, row_p in zip(dpa.successor, dpa.priority, strict=True)
                for s, p in zip(row_s, row_p, strict=True) if s == 0]
    # The initial state's priority matters only if the initial tree recurs; borrowing
    # the priority of a transition into it lets it coincide with that state.
    start = (0, min(incoming) if incoming else dpa.priority[0][0])
    index = {start: 0}
    order = [start]
    successor: list[list[int]] = []
    while len(successor) < len(order):
        tree, _ = order[len(successor)]
        row = []
        for target in zip(dpa.successor[tree], dpa.priority[tree], strict=True):
            if target not in index:
                index[target] = len(order)
                order.append(target)
                check_size(len(order), max_states, "state-based parity automaton")
            row.append(index[target])
        successor.append(row)
    priority = np.array([p for _, p in order], dtype=np.int64)
    return np.array(successor, dtype=np.int32), priority


def normalise_priorities(successor: NDArray[np.int32],
                         priority: NDArray[np.int64]) -> NDArray[np.int64]:
    """The least priorities giving every cycle the parity of its least priority.

    Carton and Maceiras (TCS 1999): in a strongly connected component whose least
    priority is ``m``, the states of priority ``m`` get the least value ``v >= floor``
    of ``m``'s parity, and the rest of the component is treated recursively with floor
    ``v``. A cycle through a state of priority ``m`` has least value ``v``; one avoiding
    them lies in a component of the rest. A state on no cycle occurs at most once in a
    run, so its priority is free: it borrows that of its successor on letter 0, which
    lets minimisation merge, e.g., a transient state with the sink it leads to.
    """
    states = len(priority)
    rows = np.repeat(np.arange(states), successor.shape[1])
    cols = successor.reshape(-1).astype(np.int64)
    result = np.full(states, -1, dtype=np.int64)
    work = [(np.ones(states, dtype=bool), 0)]
    while work:
        inside, floor = work.pop()
        keep = inside[rows] & inside[cols]
        graph = csr_array((np.ones(int(keep.sum())), (rows[keep], cols[keep])),
                          shape=(states, states))
        _, component = connected_components(graph, directed=True, connection="strong")
        size = np.bincount(component, minlength=states)
        looped = np.zeros(states, dtype=bool)
        looped[rows[keep & (rows == cols)]] = True
        cyclic = inside & ((size[component] > 1) | looped)
        nodes = np.flatnonzero(cyclic)
        if not nodes.size:
            continue
        nodes = nodes[np.argsort(component[nodes], kind="stable")]
        starts = np.flatnonzero(np.diff(component[nodes], prepend=-1))
        for group in np.split(nodes, starts[1:]):
            members = np.zeros(states, dtype=bool)
            members[group] = True
            least = int(priority[group].min())
            value = floor + (least - floor) % 2
            result[members] = value
            rest = members & (priority != least)
            if rest.any():
                work.append((rest, value))
    for state in range(states):
        # Follow letter-0 successors to a state with a value; the transient states form
        # a DAG, so the path ends, and every state on it takes that value.
        path = []
        while result[state] < 0:
            path.append(state)
            result[state] = -2  # on the current path
            state = int(successor[state, 0])
        value = int(result[state])
        result[path] = value
    return result


def minimise(successor: NDArray[np.int32],
             priority: NDArray[np.int64]) -> tuple[NDArray[np.int32], NDArray[np.int64]]:
    """The quotient by the coarsest priority-respecting bisimulation, initial state 0.

    The quotient's states are numbered in breadth-first order from the initial state,
    so that equal automata come out identical.
    """
    classes = np.unique(priority, return_inverse=True)[1].reshape(-1)
    while True:
        signature = np.column_stack([classes, classes[successor]])
        refined = np.unique(signature, axis=0, return_inverse=True)[1].reshape(-1)
        if refined.max() == classes.max():
            break
        classes = refined
    count = int(classes.max()) + 1
    representative = np.zeros(count, dtype=np.int64)
    representative[classes[::-1]] = np.arange(len(classes))[::-1]
    quotient = classes[successor[representative]]
    # Breadth-first renumbering from the initial state's class.
    number = np.full(count, -1, dtype=np.int64)
    number[classes[0]] = 0
    queue = [int(classes[0])]
    for cls in queue:
        for target in quotient[cls]:
            if number[target] < 0:
                number[target] = len(queue)
                queue.append(int(target))
    keep = np.array(queue, dtype=np.int64)
    return (number[quotient[keep]].astype(np.int32),
            priority[representative[keep]])
