"""Where the probability of reaching a target comes from: exact breakdown, likeliest paths.

For a target set ``T`` (e.g. the ``"failure"`` label), the probability of
eventually reaching ``T`` from the initial state splits exactly over the states
``T`` is entered from::

    P(F T) = sum over s not in T of  visits(s) * P(s -> T)

where ``visits(s)`` is the expected number of visits to ``s`` before ``T`` is
reached. On the states that can reach ``T`` (outside ``T``) the chain is
transient, so ``visits`` solves the sparse system ``(I - Q)^T v = e_init``
(``Q`` the transitions among those states). States that cannot reach ``T``
contribute nothing, whichever way paths pass through them.

Groupings are generic: they take named columns of values per state (a model's
variables, or a richer view such as :mod:`veribattery.analyses.mission_view`)
and sum the contributions per distinct value combination.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from veribattery._types import BoolArray, FloatArray, IntArray
from veribattery.analyses.paths import ProbablePath, most_probable_paths
from veribattery.checker import Workspace, linalg
from veribattery.checker.kernels import prob0
from veribattery.errors import CheckError
from veribattery.explore.dtmc import DTMC

__all__ = [
    "Explanation",
    "Grouping",
    "Inflow",
    "explain_target",
    "group_inflow",
    "path_rows",
    "target_inflow",
    "variable_view",
]

#: Per-state columns for grouping: name → one value per requested state.
Columns = Mapping[str, npt.NDArray[np.generic]]
#: Columns for the given state indices.
Describe = Callable[[IntArray], Columns]


@dataclass(frozen=True, slots=True)
class Inflow:
    """How ``P(F target)`` from the initial state splits over the states it is entered from.

    :ivar probability: ``P(F target)`` from the initial state.
    :ivar states: states outside the target with a transition into it (that can be visited).
    :ivar visits: expected visits to each of *states* before the target is reached.
    :ivar into: the one-step probability from each of *states* into the target.
    """

    probability: float
    states: IntArray
    visits: FloatArray
    into: FloatArray

    @property
    def contributions(self) -> FloatArray:
        """``visits * into`` per state: they sum to *probability*."""
        return np.asarray(self.visits * self.into, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class Grouping:
    """Contributions summed per distinct combination of *keys*, most probable first."""

    keys: tuple[str, ...]
    groups: tuple[tuple[tuple[object, ...], float], ...]

    def records(self) -> list[dict[str, object]]:
        """JSON-ready rows: the key values and ``probability``."""
        return [{**dict(zip(self.keys, values, strict=True)), "probability": p}
                for values, p in self.groups]


@dataclass(frozen=True, slots=True)
class Explanation:
    """The breakdown of ``P(F target)`` and the most probable paths into the target."""

    target: str
    inflow: Inflow
    groupings: tuple[Grouping, ...]
    paths: tuple[ProbablePath, ...]

    @property
    def probability(self) -> float:
        """``P(F target)`` from the initial state."""
        return self.inflow.probability


def target_inflow(dtmc: DTMC, target: BoolArray) -> Inflow:
    """The exact split of ``P(F target)`` from the (first) initial state over entering states.

    :param dtmc: the model.
    :param target: mask of the target states.
    """
    P = dtmc.transitions
    start = int(dtmc.initial[0])
    maybe = ~prob0(P, np.ones(dtmc.num_states, dtype=bool), target,
                   workspace=Workspace()) & ~target
    empty = np.zeros(0, dtype=np.int64)
    if not maybe[start]:
        return Inflow(1.0 if target[start] else 0.0, empty, np.zeros(0), np.zeros(0))
    A, rows = linalg.restricted_matrix(P, maybe)
    idx = np.flatnonzero(maybe)
    rhs = np.zeros(idx.size, dtype=np.longdouble)
    rhs[np.searchsorted(idx, start)] = 1
    visits = linalg.Factorization(sp.csr_matrix(A.T)).solve(rhs)
    into = np.asarray(rows[:, np.flatnonzero(target)].sum(axis=1)).ravel()
    entering = into > 0
    visits_in = np.maximum(visits[entering], 0.0)
    probability = float(np.sum(visits_in * into[entering]))
    return Inflow(probability, idx[entering], visits_in, into[entering])


def group_inflow(inflow: Inflow, columns: Columns, keys: Sequence[str]) -> Grouping:
    """Sum *inflow*'s contributions per distinct combination of the *keys* columns.

    :param inflow: from :func:`target_inflow`.
    :param columns: one value per state of ``inflow.states``, by name.
    :param keys: the columns to group by (at least one).
    :raises CheckError: when a key names no column.
    """
    unknown = [k for k in keys if k not in columns]
    if unknown:
        raise CheckError(f"cannot group by {', '.join(unknown)}: "
                         f"choose from {', '.join(columns)}")
    if inflow.states.size == 0:
        return Grouping(tuple(keys), ())
    codes = np.stack([np.unique(columns[k], return_inverse=True)[1].ravel() for k in keys], 1)
    uniq, first, inverse = np.unique(codes, axis=0, return_index=True, return_inverse=True)
    sums = np.bincount(inverse.ravel(), weights=inflow.contributions, minlength=uniq.shape[0])
    order = np.argsort(-sums, kind="stable")
    groups = tuple(
        (tuple(_plain(columns[k][first[g]]) for k in keys), float(sums[g])) for g in order
    )
    return Grouping(tuple(keys), groups)


def _plain(value: object) -> object:
    """A numpy scalar as the Python value JSON understands."""
    return value.item() if isinstance(value, np.generic) else value


def explain_target(
    dtmc: DTMC,
    target: BoolArray,
    *,
    name: str,
    describe: Describe | None = None,
    by: Sequence[Sequence[str]] = (),
    top: int = 3,
) -> Explanation:
    """Breakdown of ``P(F target)`` by each key combination of *by*, and the *top* paths.

    :param dtmc: the model.
    :param target: mask of the target states.
    :param name: how the target is called in reports (e.g. ``"failure"``).
    :param describe: columns for given states (default: the model's variables).
    :param by: groupings, each a sequence of column names (default: one per column).
    :param top: how many most probable paths (at least 1).
    :raises CheckError: when *top* is below 1 or a key names no column.
    """
    if top < 1:
        raise CheckError(f"--top must be at least 1, not {top}")
    inflow = target_inflow(dtmc, target)
    at_inflow = (describe or variable_view(dtmc))(inflow.states)
    chosen = [tuple(keys) for keys in by] or [(k,) for k in at_inflow]
    groupings = tuple(group_inflow(inflow, at_inflow, keys) for keys in chosen)
    paths = most_probable_paths(dtmc.transitions, int(dtmc.initial[0]), target, top)
    return Explanation(name, inflow, groupings, paths)


def variable_view(dtmc: DTMC) -> Describe:
    """The model's variables as grouping columns."""

    def describe(idx: IntArray) -> Columns:
        return {name: dtmc.states[idx, i] for i, name in enumerate(dtmc.variable_names)}

    return describe


def path_rows(
    dtmc: DTMC, path: ProbablePath, actions: Callable[[IntArray], npt.NDArray[np.str_]]
) -> list[dict[str, object]]:
    """One row per state of *path*: step, the action taken there (none at the end), variables.

    :param actions: state rows → action label (e.g. from
        :func:`veribattery.analyses.actions.action_labeller`).
    """
    rows = dtmc.states[path.states]
    labels = [str(a) for a in actions(rows)[:-1]] + [""]
    return [
        {"step": i, "action": labels[i],
         **{name: int(rows[i, c]) for c, name in enumerate(dtmc.variable_names)}}
        for i in range(rows.shape[0])
    ]
