"""Which property's strategy is exported, and the states it reaches."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from veribattery._types import BoolArray
from veribattery.checker import CheckResult
from veribattery.checker.mdp import MDP, Strategy, induced_chain
from veribattery.checker.mdp.witness import NoStrategyError, strategy_refusal
from veribattery.errors import OptionError
from veribattery.lang import FlatModel, Property
from veribattery.lang.nodes import Ident, LabelRef, Multi
from veribattery.pipeline.mdp import MdpCheckRun
from veribattery.strategies.randomised import ChosenMulti

__all__ = ["DTMC_HAS_NO_STRATEGY", "ChosenStrategy", "choose_strategy", "reached_under",
           "refuse_hopeless_export"]


@dataclass(frozen=True, slots=True)
class ChosenStrategy:
    """An optimal strategy, the property it attains and the model it acts on.

    :param result: the checked property (its resolved formula and its optimum); None
        for a strategy found otherwise (``synthesize``'s), which has a model and no
        single property.
    :param reached: the states reachable from the initial states under the strategy
        (the ones whose choice matters; the exports list only these).
    :param about: what the strategy is, for the files' headers when *result* is None.
    """

    result: CheckResult | None
    strategy: Strategy
    mdp: MDP
    model: FlatModel
    reached: BoolArray
    about: str = "the strategy"

    @property
    def reached_states(self) -> list[int]:
        """The indices of :attr:`reached`, in state order."""
        return [int(s) for s in np.flatnonzero(self.reached)]

    def valuation(self, state: int) -> dict[str, int | bool]:
        """The variables' values in *state*, in declaration order (booleans as bool)."""
        assert self.mdp.states is not None
        row = self.mdp.states[state]
        return {v.name: bool(x) if v.is_bool else int(x)
                for v, x in zip(self.model.variables, row, strict=True)}

    def action(self, state: int) -> str:
        """The action of the choice the strategy takes in *state* (``""``: unlabelled)."""
        return self.mdp.action_of(int(self.strategy.choices[state]))


def choose_strategy(run: MdpCheckRun,
                    selector: str | None = None) -> ChosenStrategy | ChosenMulti:
    """The strategy of the property *selector* names: a 1-based index among the checked
    properties or a property's name; None picks the first one that has a strategy.
    A ``multi(...)`` property's is randomised, with memory (:class:`ChosenMulti`).

    :raises OptionError: *selector* names no checked property.
    :raises NoStrategyError: the property has no strategy to export (the message
        names the property; with no *selector*: the first one).
    """
    if run.model is None:
        raise OptionError("the run did not keep its model: no strategy can be exported")
    if selector is not None:
        return _chosen_at(run, _index(run, selector))
    for index in range(len(run.results)):
        try:
            return _chosen_at(run, index)
        except NoStrategyError:
            continue
    if not run.results:
        raise OptionError("no property was checked: there is no strategy to export")
    _chosen_at(run, 0)  # raises, naming the first property
    raise AssertionError("unreachable")


def _chosen_at(run: MdpCheckRun, index: int) -> ChosenStrategy | ChosenMulti:
    """Result *index*'s strategy: randomised with memory for a ``multi(...)``, else
    memoryless deterministic; a :class:`NoStrategyError` names the property."""
    if isinstance(run.results[index].property.formula, Multi):
        return _chosen_multi(run, index)
    return _chosen(run, index, _strategy(run, index))


def _chosen_multi(run: MdpCheckRun, index: int) -> ChosenMulti:
    """The verified witness strategy of the ``multi(...)`` result *index*; an error
    names the property where it is written."""
    result = run.results[index]
    prop, formula = result.property, result.property.formula
    assert run.model is not None and isinstance(formula, Multi)
    if run.mdp.states is None or run.mdp.variable_names != run.model.variable_names:
        raise OptionError("the MDP's states do not carry the model's variables: "
                          "no strategy can be exported")
    # Imported here: the LP (scipy.optimize) is needed for multi(...) properties only.
    from veribattery.checker.mdp.multi_strategy import multi_strategy

    try:
        enclosure = None if not result.certified or result.lower is None or (
            result.upper is None) else (result.lower, result.upper)
        strategy = multi_strategy(run.mdp, formula, result.value, enclosure)
    except NoStrategyError as exc:
        raise _naming(prop, exc) from None
    return ChosenMulti.of(result, strategy, run.mdp, run.model)


def _index(run: MdpCheckRun, selector: str) -> int:
    """The 0-based position of the result *selector* names."""
    return _position([r.property for r in run.results], selector)


def _position(properties: Sequence[Property], selector: str) -> int:
    """The 0-based position among *properties* of the one *selector* names (a 1-based
    index, or a name)."""
    count = len(properties)
    if selector.isdigit():
        if not 1 <= int(selector) <= count:
            raise OptionError(f"--strategy-property {selector}: there are {count} checked "
                              "properties (1-based)")
        return int(selector) - 1
    for index, prop in enumerate(properties):
        if prop.name == selector:
            return index
    names = ", ".join(f'"{p.name}"' for p in properties if p.name)
    raise OptionError(f"--strategy-property {selector}: no checked property has that name "
                      f"(names: {names or 'none'})")


def refuse_hopeless_export(model_type: str, properties: Sequence[Property],
                           selector: str | None = None) -> None:
    """Refuse, before the model is built, a strategy export that cannot succeed: a DTMC,
    or a property (the one *selector* names; with none, every one) whose shape has no
    strategy (:func:`~veribattery.checker.mdp.witness.strategy_refusal`). A property
    that is only a reference to another (``"name"``) is judged after the check.

    :raises OptionError: a DTMC, or a *selector* that names no property.
    :raises NoStrategyError: naming the property where it is written.
    """
    if model_type != "mdp":
        raise OptionError(DTMC_HAS_NO_STRATEGY)
    if selector is not None:
        candidates = [properties[_position(properties, selector)]]
    else:
        candidates = list(properties)
    refusals = [_refusal(p) for p in candidates]
    first = refusals[0] if refusals else None
    if first is not None and all(r is not None for r in refusals):
        raise first


def _refusal(prop: Property) -> NoStrategyError | None:
    if isinstance(prop.formula, LabelRef | Ident):
        return None  # a reference: its property's shape is known once resolved
    refusal = strategy_refusal(prop.formula)
    return None if refusal is None else _naming(prop, refusal)


#: Why a DTMC has no strategy to export.
DTMC_HAS_NO_STRATEGY = ("--export-strategy/--export-induced: the model is a DTMC; only an "
                        "MDP has strategies")


def _strategy(run: MdpCheckRun, index: int) -> Strategy:
    """The strategy of result *index*; an error names the property where it is written."""
    try:
        return run.strategy(index)
    except NoStrategyError as exc:
        raise _naming(run.results[index].property, exc) from None


def _naming(prop: Property, refusal: NoStrategyError) -> NoStrategyError:
    """*refusal* as the property's own: its text first, at its position."""
    return NoStrategyError(f"{prop.text}: {refusal.message}", prop.span)


def _chosen(run: MdpCheckRun, index: int, strategy: Strategy) -> ChosenStrategy:
    assert run.model is not None
    if run.mdp.states is None or run.mdp.variable_names != run.model.variable_names:
        raise OptionError("the MDP's states do not carry the model's variables: "
                          "no strategy can be exported")
    return ChosenStrategy(run.results[index], strategy, run.mdp, run.model,
                          reached_under(run.mdp, strategy))


def reached_under(mdp: MDP, strategy: Strategy) -> BoolArray:
    """States reachable from the initial states when *strategy* picks every choice."""
    chain = induced_chain(mdp, strategy)
    reached = mdp.initial_mask
    frontier = reached.copy()
    while frontier.any():
        step = np.zeros(mdp.num_states, dtype=bool)
        rows = chain[frontier]
        step[rows.indices[rows.data > 0]] = True
        frontier = step & ~reached
        reached |= frontier
    return reached
