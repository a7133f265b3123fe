"""Where exploration may stop: states at which every property's value is known.

A property read at the initial states whose operators are ``P [ a U b ]``, ``P [ F b ]``,
``P [ G a ]`` (unbounded, or with an upper step bound) or ``R [ F b ]``, over state
formulas without operators, reads nothing past a state where the path formula is
already decided: ``b``, or neither ``a`` nor ``b`` (for ``F b``: ``b``; for ``G a``:
``!a``). Its value there is 1, 0 or no more reward, whatever follows, and on an MDP a
strategy's choice there changes nothing. Storm's builder, given such properties, leaves
those states unexpanded (its *terminal states*); the states reached only through them
are never built, and the values at the initial states are the same.

Anything else reads the values of states past those (a filter over all states, a nested
operator, ``X``, a lower step bound, total or cumulative reward, ``multi``), and then
every state is built. So is a property that reads the built-in ``"deadlock"`` or
``"init"`` label, which an unexpanded state cannot answer.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from veribattery.lang.expressions import children, substitute, walk
from veribattery.lang.nodes import (
    Binary,
    BoolLit,
    Call,
    DoubleLit,
    Eventually,
    Expr,
    FlatModel,
    Globally,
    Ident,
    IntLit,
    Ite,
    LabelRef,
    ProbOp,
    Property,
    Reach,
    RewardOp,
    TimeBound,
    Unary,
    Until,
)

__all__ = ["stopping_condition"]

#: The nodes of a state formula without operators.
_STATE_NODES = (IntLit, DoubleLit, BoolLit, Ident, LabelRef, Unary, Binary, Ite, Call)


def stopping_condition(properties: Sequence[Property], model: FlatModel) -> Expr | None:
    """The state formula over *model*'s variables (its labels inlined) where exploration
    may stop for every one of the resolved *properties*, or None where some property
    reads past such states, or where none has an operator to stop for."""
    labels = {label.name: label.expr for label in model.labels}
    conditions: list[Expr] = []
    for prop in properties:
        found = _conditions(prop.formula)
        if found is None:
            return None
        conditions.extend(found)
    if not conditions:
        return None
    inlined = [_inlined(condition, labels) for condition in conditions]
    if any(condition is None for condition in inlined):
        return None
    joined: Expr = inlined[0]  # type: ignore[assignment]
    for condition in inlined[1:]:
        joined = Binary("&", joined, condition)  # type: ignore[arg-type]
    return joined


def _conditions(formula: Expr) -> list[Expr] | None:
    """Per operator of *formula*, where its value is decided; None where one reads
    further (or *formula* has a node of any other kind)."""
    if isinstance(formula, ProbOp | RewardOp):
        decided = _decided(formula)
        return None if decided is None else [decided]
    if isinstance(formula, IntLit | DoubleLit | BoolLit | Ident):
        return []
    if isinstance(formula, LabelRef):
        return None if formula.name in ("deadlock", "init") else []
    if isinstance(formula, Unary | Binary | Ite | Call):
        found: list[Expr] = []
        for child in children(formula):
            below = _conditions(child)
            if below is None:
                return None
            found.extend(below)
        return found
    return None


def _decided(operator: ProbOp | RewardOp) -> Expr | None:
    """Where *operator*'s path formula is decided, or None where it reads further."""
    path: Any = operator.path
    if isinstance(operator, RewardOp):
        return path.target if type(path) is Reach and _stateless(path.target) else None
    if type(path) not in (Eventually, Until, Globally) or not _upper_bound_only(path.bound):
        return None
    if type(path) is Eventually:
        decided = path.operand
    elif type(path) is Globally:
        decided = Unary("!", path.operand)
    else:
        decided = Binary("|", path.right, Unary("!", path.left))
    return decided if _stateless(decided) else None


def _upper_bound_only(bound: object) -> bool:
    return bound is None or (type(bound) is TimeBound and bound.op in ("<", "<="))


def _stateless(formula: Expr) -> bool:
    """Whether *formula* is a state formula without operators and built-in labels."""
    return all(isinstance(node, _STATE_NODES)
               and not (type(node) is LabelRef and node.name in ("deadlock", "init"))
               for node in walk(formula))


def _inlined(condition: Expr, labels: Mapping[str, Expr]) -> Expr | None:
    """*condition* with each label replaced by its expression; None for an unknown one."""
    if any(type(node) is LabelRef and node.name not in labels for node in walk(condition)):
        return None

    def replace(node: Any) -> Any | None:
        return labels[node.name] if type(node) is LabelRef else None

    return substitute(condition, replace)  # type: ignore[no-any-return]
