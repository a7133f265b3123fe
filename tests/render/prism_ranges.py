"""PRISM's symbolic range check, done with Storm's expressions: over the WHOLE domain of
the variables (Storm itself only explores reachable states), does any command's own guard
admit an update out of range? Shared by the DTMC's and the MDP's tests; import it only
after ``pytest.importorskip("stormpy")``."""

from __future__ import annotations

import itertools
from pathlib import Path

import stormpy


def range_violations(text: str, tmp_path: Path) -> set[tuple[str, str]]:
    """The (module, variable) pairs some command of *text* can push out of range."""
    path = tmp_path / "ranges.prism"
    path.write_text(text)
    program = stormpy.parse_prism_program(str(path)).substitute_formulas().substitute_constants()
    manager = program.expression_manager
    bounds = {
        v.name: (
            v.expression_variable,
            v.lower_bound_expression.evaluate_as_int(),
            v.upper_bound_expression.evaluate_as_int(),
        )
        for module in program.modules
        for v in module.integer_variables
    }
    commands = [
        (
            module.name,
            c.guard_expression,
            [(a.variable.name, a.expression) for u in c.updates for a in u.assignments],
        )
        for module in program.modules
        for c in module.commands
    ]
    bad: set[tuple[str, str]] = set()
    for values in itertools.product(*(range(lo, hi + 1) for _, lo, hi in bounds.values())):
        sub = {
            var: manager.integer(x) for (var, _, _), x in zip(bounds.values(), values, strict=True)
        }
        for module, guard, assignments in commands:
            if guard.substitute(sub).evaluate_as_bool():
                for name, expr in assignments:
                    _, lo, hi = bounds[name]
                    if not lo <= expr.substitute(sub).evaluate_as_int() <= hi:
                        bad.add((module, name))
    return bad
