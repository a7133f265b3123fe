"""Long operator chains evaluated in a loop instead of nested calls.

A compiled expression is a tree of closures, each calling its operands'. A chain
such as ``a | b | c | ...`` (left-nested), ``a | (b | (c | ...))`` (right-nested) or
``c1 ? v1 : c2 ? v2 : ...`` (nested in the last branch) becomes a nest of calls as
deep as it is long, and a chain of a few hundred links exceeds Python's recursion
limit at run time. Each compiled node made from operands therefore also records a
:class:`Link`: how its value follows from that of its deepest operand (its *below*).
A node deep in such a chain gets the evaluator of :func:`unrolled`, which runs the
links of the whole chain in a loop, in the order the nested calls would have run
them, with the same numpy operations.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from veribattery._types import IntArray

__all__ = ["SPINE_LIMIT", "Link", "Linked", "same_rows", "unrolled"]

#: Chains up to this many links keep their nested calls (at most a few hundred frames,
#: and the fastest form); a node further down a chain is evaluated by :func:`unrolled`.
SPINE_LIMIT = 48


class Linked(Protocol):
    """A compiled node as this module sees it."""

    @property
    def fn(self) -> Callable[[IntArray], Any]: ...

    @property
    def link(self) -> Link | None: ...


@dataclass(frozen=True, slots=True)
class Link:
    """How a node's value is made from the value of its operand *below*.

    *descend* runs before *below*, on the node's rows, and evaluates what comes
    before it: it returns what the node keeps for later and the rows *below* is
    evaluated on (for ``? :``, the condition and the branch taken, and the other
    rows), or the node's value and None when *below* is not needed at all (``a | b``
    with ``a`` true in every row). *combine* then makes the node's value from what
    was kept and *below*'s value.
    """

    below: Linked
    descend: Callable[[IntArray], tuple[Any, IntArray | None]]
    combine: Callable[[Any, Any], Any]


def same_rows(states: IntArray) -> tuple[IntArray, IntArray | None]:
    """:attr:`Link.descend` of a node whose operand *below* is evaluated first, on the
    same rows (an operator over its left operand): the rows are all it keeps."""
    return states, states


def unrolled(link: Link) -> Callable[[IntArray], Any]:
    """The evaluator of a node made by *link*: its chain's links in a loop.

    The chain is followed down from *link* to the first node without a link when
    the evaluator first runs, and kept: a node whose evaluator never runs (a
    prefix of a longer chain) costs nothing.
    """
    followed: list[tuple[list[Link], Callable[[IntArray], Any]]] = []

    def follow() -> tuple[list[Link], Callable[[IntArray], Any]]:
        links: list[Link] = []
        current: Link | None = link
        while current is not None:
            links.append(current)
            current = current.below.link
        followed.append((links, links[-1].below.fn))  # two threads may both append: equal
        return followed[0]

    def evaluate(states: IntArray) -> Any:
        links, bottom = followed[0] if followed else follow()
        kept = []
        for step in links:
            context, rows = step.descend(states)
            if rows is None:  # decided here: *context* is this link's value
                value = context
                break
            kept.append(context)
            states = rows
        else:
            value = bottom(states)
        for step, context in zip(reversed(links[: len(kept)]), reversed(kept), strict=True):
            value = step.combine(context, value)
        return value

    return evaluate
