"""The initial states of a flat model: its variables' init values, or the states of
the variables' domain that satisfy its ``init`` block.

An ``init`` block usually pins most variables (``coin1=0 & s1=0 & ...``, with ``pay``
free: PRISM's dining cryptographers): its domain of 12^6 x 7 states holds 7 initial
ones. So each disjunct of the block is searched on its own, over the values that its
single-variable conjuncts allow (``s1=0`` leaves one value of ``s1``), and only that
product is enumerated and tested against the whole disjunct.
"""

from __future__ import annotations

import numpy as np

from veribattery._types import IntArray
from veribattery.errors import ModelError
from veribattery.explore.compile.expr import compile_expr
from veribattery.lang.expressions import operand_chain, walk
from veribattery.lang.nodes import Expr, FlatModel, Ident

__all__ = ["initial_states"]

#: Rows of a domain enumerated at once when evaluating an ``init`` block.
_INIT_CHUNK = 1 << 20
#: The most rows an ``init`` block may be tested on.
_INIT_LIMIT = 1 << 40


def initial_states(model: FlatModel) -> IntArray:
    """The initial states of *model*: its variables' init values, or the domain
    states that satisfy its ``init`` block, in lexicographic order (first variable
    most significant)."""
    if model.init is None:
        return np.array([[v.init for v in model.variables]], dtype=np.int64)
    names = model.variable_names
    full = [np.arange(v.low, v.high + 1, dtype=np.int64) for v in model.variables]
    terms = [(term, _allowed(term, names, full)) for term in operand_chain(model.init, "|")]
    if _size(full) <= sum(_size(domains) for _, domains in terms):
        terms = [(model.init, full)]  # no disjunct narrows much: one pass over it all
    found = [_satisfying(term, names, domains) for term, domains in terms]
    rows = np.concatenate(found)
    if rows.shape[0] == 0:
        raise ModelError("the init block is satisfied by no state",
                         getattr(model.init, "span", None))
    return np.unique(rows, axis=0) if len(found) > 1 else rows


def _allowed(term: Expr, names: tuple[str, ...], full: list[IntArray]) -> list[IntArray]:
    """Per variable, the values that *term*'s conjuncts over that variable alone allow
    (a closed false conjunct allows none)."""
    domains = list(full)
    for conjunct in operand_chain(term, "&"):
        read = {node.name for node in walk(conjunct) if isinstance(node, Ident)}
        if len(read) > 1:
            continue
        if not read:
            holds = np.asarray(compile_expr(conjunct, ())(np.zeros((1, 0), dtype=np.int64)))
            if not holds.all():
                return [values[:0] for values in domains]
            continue
        i = names.index(read.pop())
        holds = compile_expr(conjunct, (names[i],))(domains[i][:, None])
        domains[i] = domains[i][np.broadcast_to(np.asarray(holds, dtype=bool),
                                                domains[i].shape)]
    return domains


def _satisfying(term: Expr, names: tuple[str, ...], domains: list[IntArray]) -> IntArray:
    """The rows of the product of *domains* that satisfy *term*, in order."""
    total = _size(domains)
    if total > _INIT_LIMIT:
        raise ModelError(f"init block ranges over {total} states: too many to enumerate")
    predicate = compile_expr(term, names)
    found = [rows[np.broadcast_to(np.asarray(predicate(rows), dtype=bool), rows.shape[:1])]
             for rows in (_product_rows(domains, s, min(s + _INIT_CHUNK, total))
                          for s in range(0, total, _INIT_CHUNK))]
    return np.concatenate(found) if found else np.empty((0, len(domains)), dtype=np.int64)


def _size(domains: list[IntArray]) -> int:
    """The number of rows of the product of *domains* (exact: it may pass 2^63)."""
    return int(np.prod([values.size for values in domains], dtype=object))


def _product_rows(domains: list[IntArray], start: int, stop: int) -> IntArray:
    """Rows ``start..stop-1`` of the product of *domains* in mixed-radix order."""
    flat = np.arange(start, stop, dtype=np.int64)
    rows = np.empty((flat.size, len(domains)), dtype=np.int64)
    for i in range(len(domains) - 1, -1, -1):
        flat, digit = np.divmod(flat, domains[i].size)
        rows[:, i] = domains[i][digit]
    return rows
