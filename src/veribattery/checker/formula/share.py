"""Shared linear systems: which unbounded queries of a property list solve on one system.

Before the properties of a model are checked, :func:`share_systems` looks at their
operator-free operands and builds the linear systems that several queries can share
(``docs/numerics.md``, "Shared systems"), so that the order the properties are then
checked in does not matter.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from veribattery._types import BoolArray
from veribattery.checker import kernels
from veribattery.checker.formula.leaves import _everywhere, has_operator
from veribattery.checker.formula.pctl import state_set
from veribattery.errors import VeribatteryError
from veribattery.explore.dtmc import DTMC
from veribattery.lang.nodes import (
    Conditional,
    ConditionalReach,
    Eventually,
    Expr,
    ProbOp,
    Reach,
    RewardOp,
    Until,
)

if TYPE_CHECKING:
    from veribattery.checker.workspace import Workspace


def share_systems(dtmc: DTMC, workspace: Workspace, formulas: Sequence[Expr]) -> None:
    """Let the unbounded queries among *formulas* share one linear system in *workspace*,
    whatever the order they are checked in with it
    (:meth:`~veribattery.checker.workspace.Workspace.prepare`).

    A ``P=? [ a U b ]`` whose unknown states lie inside those of an ``R=? [ F c ]``
    (and outside ``b``, inside ``a``) is solved on the latter's system (see
    :func:`kernels.shared_system`); when such a pair exists, the reward query's system
    is built first. Without reward queries, several untils share one system on the
    union of their unknowns where that is cheaper (:func:`kernels.prepare_untils`:
    a Fig. 6 point's ``P=? [ F "success" ]`` and the recharge cap's probability).
    Only operator-free operands are looked at (their masks are cheap); the pre-pass
    results are kept in *workspace*, so checking repeats none of this work. The conditions of
    conditional properties are marked as needed in every state
    (:func:`kernels.need_whole`): a ``P=? [ F b ]`` among the properties then shares them.
    """
    P = dtmc.transitions
    conditions = (_condition_set(dtmc, workspace, f) for f in formulas)
    for condition in (c for c in conditions if c is not None):
        kernels.need_whole(P, _everywhere(dtmc), condition, workspace=workspace)
    reach = [m for m in (_reach_target(dtmc, workspace, f) for f in formulas) if m is not None]
    untils = [u for u in (_until_operands(dtmc, workspace, f) for f in formulas) if u is not None]
    for target in reach if untils else ():
        unknowns = kernels.reach_unknowns(P, target, workspace=workspace)
        if any(_inside(kernels.until_unknowns(P, *until, workspace=workspace), unknowns)
               for until in untils):
            kernels.prepare_reach(P, target, workspace=workspace)
            return
    if len(untils) > 1 and not reach:
        kernels.prepare_untils(P, untils, workspace=workspace)


def _inside(query: tuple[BoolArray, BoolArray], unknowns: BoolArray) -> bool:
    """Whether a query's unknowns lie in *unknowns*, all of which satisfy its equations."""
    maybe, allowed = query
    return bool(maybe.any() and not np.any(maybe & ~unknowns)
                and not np.any(unknowns & ~allowed))


def _reach_target(dtmc: DTMC, workspace: Workspace, formula: Expr) -> BoolArray | None:
    """The target of an ``R=? [ F a ]`` (or ``[ F a || F b ]``) with an operator-free *a*."""
    if not (isinstance(formula, RewardOp) and formula.op == "=?"):
        return None
    path = formula.path
    if isinstance(path, Reach | ConditionalReach) and not has_operator(path.target):
        return _quiet_set(dtmc, workspace, path.target)
    return None


def _condition_set(dtmc: DTMC, workspace: Workspace, formula: Expr) -> BoolArray | None:
    """The states *b* of an operator-free condition ``F b`` of a conditional ``P=?``/``R=?``."""
    if not (isinstance(formula, ProbOp | RewardOp) and formula.op == "=?"):
        return None
    path = formula.path
    if isinstance(path, ConditionalReach | Conditional) and not has_operator(path.condition):
        return _quiet_set(dtmc, workspace, path.condition)
    return None


def _until_operands(dtmc: DTMC, workspace: Workspace, formula: Expr
                    ) -> tuple[BoolArray, BoolArray] | None:
    """``(remain, target)`` of an unbounded ``P=? [ F b ]`` / ``[ a U b ]``, operator-free."""
    if not (isinstance(formula, ProbOp) and formula.op == "=?"):
        return None
    match formula.path:
        case Eventually(operand=operand, bound=None) if not has_operator(operand):
            target = _quiet_set(dtmc, workspace, operand)
            return None if target is None else (_everywhere(dtmc), target)
        case Until(left=left, right=right, bound=None) if not (
                has_operator(left) or has_operator(right)):
            a, b = _quiet_set(dtmc, workspace, left), _quiet_set(dtmc, workspace, right)
            return None if a is None or b is None else (a, b)
    return None


def _quiet_set(dtmc: DTMC, workspace: Workspace, expr: Expr) -> BoolArray | None:
    """:func:`state_set` of an operator-free *expr*, or None where it would fail
    (the check itself then reports the error)."""
    try:
        return state_set(dtmc, workspace, expr)
    except VeribatteryError:
        return None
