"""CTL on the graph of a DTMC: ``E``/``A`` over ``X F G U W R`` as graph algorithms.

Paths are the infinite paths through transitions of positive probability
(deadlocks carry a self-loop, so every state has one). The kernels are the
existential ones -- ``EX``, ``E[a U b]`` (backward reachability) and ``EG a``
(reach, inside *a*, a strongly connected part of *a* with an internal edge) --
and everything else reduces to them by PRISM's identities:
``a W b = !((a&!b) U (!a&!b))``, ``a R b = !(!a U !b)``, ``A phi = !E !phi``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, cast

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from veribattery._types import BoolArray, CsrMatrix, IntArray
from veribattery.checker import kernels
from veribattery.errors import CheckError
from veribattery.lang.nodes import (
    Eventually,
    Expr,
    Globally,
    Next,
    PathFormula,
    Release,
    Until,
    WeakUntil,
)

if TYPE_CHECKING:
    from veribattery.checker.workspace import Workspace


#: The path operators ``A [...]`` and ``E [...]`` take, by node type.
_OPERATORS: Mapping[type, str] = MappingProxyType(
    {Next: "X", Eventually: "F", Globally: "G", Until: "U", WeakUntil: "W", Release: "R"})


def _path_operands(path: PathFormula) -> tuple[str, Expr, Expr]:
    """``(op, left, right)`` of a CTL path (*left* is *right* for ``X``, ``F``, ``G``).

    :raises CheckError: for a step bound or a conditional formula, which PRISM's CTL
        does not take either.
    """
    if getattr(path, "bound", None) is not None:
        raise CheckError("time-bounded temporal operators are not supported in CTL "
                         "(A [...] and E [...]), as in PRISM", path.span)
    op = _OPERATORS.get(type(path))
    if op is None:
        raise CheckError("A [...] and E [...] take X, F, G, U, W or R, not a conditional (||) "
                         "formula", path.span)
    if isinstance(path, Until | WeakUntil | Release):
        return op, path.left, path.right
    operand = cast(Eventually | Globally | Next, path).operand
    return op, operand, operand


def state_pattern(transitions: CsrMatrix, owner: IntArray, num_states: int) -> sp.csr_matrix:
    """The state graph of a choice matrix (row *c* owned by state ``owner[c]``): an edge
    wherever some choice has a positive entry, as the 0/1 matrix CTL reads."""
    coo = transitions.tocoo()
    keep = coo.data > 0
    rows = np.asarray(owner)[coo.row[keep]]
    graph = sp.csr_matrix((np.ones(rows.size), (rows, coo.col[keep])),
                          shape=(num_states, num_states))
    graph.data[:] = 1.0  # duplicates summed
    return graph


def _graph(P: CsrMatrix, rows: BoolArray, cols: BoolArray) -> sp.csr_matrix:
    """The edges of *P* with positive probability from *rows* to *cols*, as 0/1."""
    coo = P.tocoo()
    keep = (coo.data > 0) & rows[coo.row] & cols[coo.col]
    return sp.csr_matrix((np.ones(int(keep.sum())), (coo.row[keep], coo.col[keep])),
                         shape=P.shape)


def exists_next(P: CsrMatrix, target: BoolArray) -> BoolArray:
    """States with a successor in *target* (``E [X target]``)."""
    return np.asarray(_graph(P, np.ones_like(target), target) @ target.astype(np.float64) > 0)


def exists_until(P: CsrMatrix, remain: BoolArray, target: BoolArray, *,
                 workspace: Workspace) -> BoolArray:
    """States with a path through *remain* to *target* (``E [remain U target]``)."""
    return ~kernels.prob0(P, remain, target, workspace=workspace)


def exists_globally(P: CsrMatrix, inside: BoolArray, *, workspace: Workspace) -> BoolArray:
    """States with an infinite path that stays in *inside* (``E [G inside]``)."""
    graph = _graph(P, inside, inside)
    _, scc = csgraph.connected_components(graph, directed=True, connection="strong")
    coo = graph.tocoo()
    # An SCC holds an infinite path iff it has an edge inside it (a self-loop counts).
    internal = scc[coo.row] == scc[coo.col]
    cyclic_scc = np.zeros(int(scc.max()) + 1 if scc.size else 0, dtype=bool)
    cyclic_scc[scc[coo.row[internal]]] = True
    cyclic = inside & cyclic_scc[scc]
    return exists_until(P, inside, cyclic, workspace=workspace)


def _exists(P: CsrMatrix, op: str, left: BoolArray, right: BoolArray,
            workspace: Workspace) -> BoolArray:
    """``E [left op right]`` for op in X F G U W R (unary operators use *right*)."""
    if op == "X":
        return exists_next(P, right)
    if op == "F":
        return exists_until(P, np.ones_like(right), right, workspace=workspace)
    if op == "G":
        return exists_globally(P, right, workspace=workspace)
    if op == "U":
        return exists_until(P, left, right, workspace=workspace)
    if op == "W":
        return (exists_until(P, left, right, workspace=workspace)
                | exists_globally(P, left, workspace=workspace))
    # a R b: b holds until and including the first a, or forever.
    return (exists_until(P, right, left & right, workspace=workspace)
            | exists_globally(P, right, workspace=workspace))


def quantified_path(P: CsrMatrix, quantifier: str, path: PathFormula,
                    mask: Callable[[Expr], BoolArray], *, workspace: Workspace) -> BoolArray:
    """``A [path]``/``E [path]`` (unbounded ``X F G U W R``, as PRISM's CTL) on the graph
    of *P*, its operands' states given by *mask* (in floats or exactly: the same sets).

    :raises CheckError: for a step bound or a conditional formula.
    """
    op, left, right = _path_operands(path)
    b = mask(right)
    a = b if left is right else mask(left)
    return quantified(P, quantifier, op, a, b, workspace=workspace)


def quantified(P: CsrMatrix, quantifier: str, op: str, left: BoolArray,
               right: BoolArray, *, workspace: Workspace) -> BoolArray:
    """``A``/``E`` applied to the path ``left op right`` (``op`` in X F G U W R).

    :param P: row-stochastic CSR transition matrix.
    :param quantifier: ``"A"`` (all paths) or ``"E"`` (some path).
    :param op: the temporal operator; for X, F and G only *right* is used.
    :param left: the left operand's states (ignored by unary operators).
    :param right: the (right) operand's states.
    :param workspace: where the graph searches are memoised.
    """
    if quantifier == "E":
        return _exists(P, op, left, right, workspace)
    # A phi = !E !phi, with the negated path in the same operator family.
    dual = {
        "X": lambda: _exists(P, "X", left, ~right, workspace),
        "F": lambda: _exists(P, "G", left, ~right, workspace),
        "G": lambda: _exists(P, "F", left, ~right, workspace),
        "U": lambda: _exists(P, "W", ~right, ~left & ~right, workspace),
        "W": lambda: _exists(P, "U", left & ~right, ~left & ~right, workspace),
        "R": lambda: _exists(P, "U", ~left, ~right, workspace),
    }
    return ~dual[op]()
