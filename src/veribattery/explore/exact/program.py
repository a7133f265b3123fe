"""Guards, assignments and labels decided in exact rational arithmetic (``--exact``).

The float builder evaluates ``x*0.1 <= 0.3`` in doubles, where ``3*0.1`` is
0.30000000000000004: the guard is false at ``x = 3`` although it holds of the
numbers as written. Under ``--exact`` every guard, assignment, label and reward
guard whose flat form does arithmetic that doubles may round (a double literal,
a division, ``pow``, ``log``) is evaluated instead from the model's *source*
expression in rationals -- formulas inlined, constants exact (``const double
step = 0.1`` is 1/10) -- once per distinct valuation of the variables it reads.
Integer-only expressions are exact in their compiled form already and are kept
as they are, and so is ``floor(a/b)``/``ceil(a/b)`` of integer expressions whose
magnitudes interval analysis bounds by 2^50: a quotient of integers that is not
itself an integer lies at least ``1/|b|`` from every integer, farther than the
double division's rounding error, so its floor and ceiling are exact (the
mission's ``floor(C_NEW*(500 - rc)/500)``; its build is unchanged).

This is PRISM's and the issue's semantics of ``-exact``. Storm's exact engine
differs: it evaluates probabilities in rationals but guards in doubles, so on
such a model the two state spaces differ (see ``tests/explore/test_exact_guards.py``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from veribattery._types import IntArray
from veribattery.explore.compile.bounds import value_bounds
from veribattery.explore.compile.expr import CompiledExpr
from veribattery.explore.compile.program import CompiledCommand, CompiledUpdate, Program
from veribattery.explore.dtmc import DTMC
from veribattery.explore.exact.rational import ExactScalar, tabulate
from veribattery.lang.expressions import children
from veribattery.lang.nodes import (
    Binary,
    Call,
    Command,
    DoubleLit,
    Expr,
    FlatModel,
    Ident,
    Update,
)

__all__ = ["ExactSource", "exact_labels", "exact_program", "needs_exact"]

#: Functions whose double result may differ from the exact one (or that have none).
_ROUNDING_CALLS = frozenset({"pow", "log"})


#: Integers up to this magnitude divide exactly enough for floor/ceil in doubles.
_SAFE_MAGNITUDE = 2.0**50


def needs_exact(expr: Expr, ranges: Mapping[str, tuple[int, int]] | None = None) -> bool:
    """Whether evaluating *expr* (a flat expression) in doubles may round.

    :param ranges: the variables' ranges, to bound the operands of ``floor(a/b)``.
    """
    bounds = {name: (float(low), float(high)) for name, (low, high) in (ranges or {}).items()}
    return _rounds(expr, bounds)


def _rounds(expr: Expr, bounds: Mapping[str, tuple[float, float]]) -> bool:
    """Whether some node of *expr* may round (a walk of its own: chains are long)."""
    stack = [expr]
    seen: set[int] = set()  # formulas are inlined as shared sub-trees
    while stack:
        node = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, DoubleLit):
            return True
        if isinstance(node, Binary) and node.op == "/":
            return True
        if isinstance(node, Call):
            if node.func in _ROUNDING_CALLS:
                return True
            if node.func in ("floor", "ceil") and _exact_quotient(node.args[0], bounds):
                continue
        stack.extend(children(node))
    return False


def _exact_quotient(expr: Expr, bounds: Mapping[str, tuple[float, float]]) -> bool:
    """*expr* is ``a/b`` of bounded integer expressions (its floor is exact in doubles)."""
    if not (isinstance(expr, Binary) and expr.op == "/"):
        return False
    for operand in (expr.left, expr.right):
        interval = value_bounds(operand, bounds)
        if _rounds(operand, bounds) or interval is None:
            return False
        if max(abs(interval[0]), abs(interval[1])) > _SAFE_MAGNITUDE:
            return False
    return True


@dataclass(frozen=True, slots=True)
class ExactSource:
    """What exact evaluation needs: exact constants, variable columns, source expressions.

    :param commands: each flat command (by ``id``) and the command as written.
    :param labels: each label's expression as written (formulas inlined).
    """

    constants: Mapping[str, ExactScalar]
    columns: Mapping[str, tuple[int, bool]]
    commands: Mapping[int, Command]
    labels: Mapping[str, Expr]
    ranges: Mapping[str, tuple[int, int]]

    def rounds(self, expr: Expr) -> bool:
        """Whether the flat *expr* may round in doubles (see :func:`needs_exact`)."""
        return needs_exact(expr, self.ranges)

    def function(self, expr: Expr, convert: Callable[[np.ndarray], np.ndarray]) -> CompiledExpr:
        """*expr* as a function of the state rows, evaluated exactly (see :func:`tabulate`)."""

        def evaluate(states: IntArray) -> np.ndarray:
            return tabulate(expr, self.constants, self.columns, states, convert)

        return evaluate


def as_bools(table: np.ndarray) -> np.ndarray:
    """A table of exact booleans as a numpy bool array."""
    return np.asarray(table, dtype=bool)


def as_numbers(table: np.ndarray) -> np.ndarray:
    """A table of exact values as int64 when all are integers, else as doubles.

    A non-integer value assigned to an int variable is then reported by the
    builder's own range and type checks, as on the float path.
    """
    if table.dtype == bool:
        return table
    if all(v.denominator == 1 for v in table):
        return np.array([int(v) for v in table], dtype=np.int64)
    return np.array([float(v) for v in table], dtype=np.float64)


def exact_program(program: Program, flat: FlatModel, source: ExactSource) -> Program:
    """*program* with every rounding-prone guard and assignment evaluated exactly."""
    updates = {id(c): c.updates for m in flat.modules for c in m.commands}

    def command(compiled: CompiledCommand) -> CompiledCommand:
        return _exact_command(compiled, updates[id(compiled.command)], source)

    groups = tuple(
        replace(g, parts=tuple(tuple(command(c) for c in part) for part in g.parts))
        for g in program.groups
    )
    return replace(program, groups=groups, exact=True)


def _exact_command(
    compiled: CompiledCommand, flat_updates: tuple[Update, ...], source: ExactSource
) -> CompiledCommand:
    written = source.commands[id(compiled.command)]
    changed = compiled
    if source.rounds(compiled.command.guard):
        guard = source.function(written.guard, as_bools)
        changed = replace(changed, guard=guard, always=False)
    updates = tuple(
        _exact_update(u, flat, w, source)
        for u, flat, w in zip(compiled.updates, flat_updates, written.updates, strict=True)
    )
    return replace(changed, updates=updates)


def _exact_update(
    compiled: CompiledUpdate, flat: Update, written: Update, source: ExactSource
) -> CompiledUpdate:
    """Exact right-hand sides where rounding could change the successor (range checked)."""
    assignments = []
    unchecked = set(compiled.unchecked)
    # The compiler drops identity assignments (x'=x): pair the rest in order.
    kept = [(f, w) for f, w in zip(flat.assignments, written.assignments, strict=True)
            if not (isinstance(f.expr, Ident) and f.expr.name == f.variable)]
    pairs = ((c, f, w) for c, (f, w) in zip(compiled.assignments, kept, strict=True))
    for (column, rhs), flat_assignment, assignment in pairs:
        if source.rounds(flat_assignment.expr):
            rhs = source.function(assignment.expr, as_numbers)
            unchecked.discard(column)  # interval analysis ran on the rounded form
        assignments.append((column, rhs))
    return replace(compiled, assignments=tuple(assignments), unchecked=frozenset(unchecked))


def exact_labels(dtmc: DTMC, flat: FlatModel, source: ExactSource) -> DTMC:
    """*dtmc* with each rounding-prone label recomputed exactly over its states."""
    labels = dict(dtmc.labels)
    for label in flat.labels:
        if source.rounds(label.expr):
            labels[label.name] = source.function(source.labels[label.name], as_bools)(dtmc.states)
    return replace(dtmc, labels=labels)
