"""A state's valuation as PRISM text: the strategy files' state tuples, and the guards
and updates of the induced models' commands (both the deterministic and the
randomised strategy's)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

__all__ = ["distribution_text", "guard_text", "state_text", "update_text", "value_text"]

#: Variable name -> value (booleans as ``bool``), in the model's order.
Valuation = Mapping[str, int | bool]


def value_text(value: int | bool) -> str:
    """``true``/``false`` for a boolean, else the integer."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(int(value))


def state_text(valuation: Valuation) -> str:
    """``(1,0,true)``: PRISM's text of a state, in the strategy files."""
    return "(" + ",".join(value_text(v) for v in valuation.values()) + ")"


def guard_text(valuation: Valuation) -> str:
    """``s=1 & !b``: the guard that holds in this valuation only (``true`` if empty)."""
    return " & ".join(_test(name, value) for name, value in valuation.items()) or "true"


def _test(name: str, value: int | bool) -> str:
    if isinstance(value, bool):
        return name if value else f"!{name}"
    return f"{name}={value}"


def update_text(before: Valuation, after: Valuation) -> str:
    """The assignments that take *before* to *after* (``true`` if none changes)."""
    changed = [f"({name}'={value_text(after[name])})"
               for name in after if after[name] != before[name]]
    return "&".join(changed) or "true"


def distribution_text(valuation: Callable[[int], Valuation], source: int,
                      targets: Sequence[tuple[int, float]]) -> str:
    """A command's updates from *source* to each of *targets* (``(state, probability)``,
    states read through *valuation*); one target needs no probability."""
    before = valuation(source)
    if len(targets) == 1:
        return update_text(before, valuation(targets[0][0]))
    return " + ".join(f"{p!r}:{update_text(before, valuation(t))}" for t, p in targets)
