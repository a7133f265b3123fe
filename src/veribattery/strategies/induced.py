"""The DTMC a strategy induces, as a PRISM model and properties file.

The encoding keeps the MDP's variables, so labels, rewards and properties read as
they did on the MDP: one module, the model's variables with their ranges and initial
values, and per state reachable under the strategy one command, guarded by the
state's valuation, labelled by the action the strategy takes there, with the
distribution of that choice. The model's labels and reward structures follow,
closed (constants as literals, formulas inlined), so that ``[a]`` transition rewards
apply to the chosen command exactly as they did to the chosen choice. A state that was
a deadlock in the MDP gets no command here either: every tool fixes it with the same
self-loop (and the built-in ``"deadlock"`` label keeps its meaning).

The properties file holds the property in its DTMC form: ``Pmax=?``, ``Pmin=?`` and
``P~p`` become ``P=?`` over the same path (``R`` likewise), whose value on the induced
DTMC is the MDP's optimum.
"""

from __future__ import annotations

from collections.abc import Iterator

from veribattery.lang import FlatModel
from veribattery.lang.nodes import (
    Binary,
    Expr,
    ProbOp,
    Release,
    RewardItem,
    RewardOp,
    RewardStruct,
    Unary,
    Until,
    Variable,
    WeakUntil,
)
from veribattery.lang.printing import expression_text, path_text, reward_path_text
from veribattery.lang.property_rules import STEPS_REWARD
from veribattery.strategies.chosen import ChosenStrategy
from veribattery.strategies.valuation_text import distribution_text, guard_text, value_text

__all__ = [
    "INDUCED_MODEL",
    "INDUCED_PROPERTIES",
    "dtmc_property_text",
    "induced_model_text",
    "induced_properties_text",
    "labels_text",
]

#: File names of the induced model and its properties inside ``--export-induced DIR``.
INDUCED_MODEL = "induced.prism"
INDUCED_PROPERTIES = "induced.props"


def induced_model_text(chosen: ChosenStrategy) -> str:
    """The induced DTMC as a PRISM ``dtmc`` model (see the module's description)."""
    model = chosen.model
    parts = [
        _header(chosen),
        "dtmc\n\nmodule strategy\n",
        *(f"  {_declaration(v, model.init is None)}\n" for v in model.variables),
        "\n",
        *(f"  {command}\n" for command in _commands(chosen)),
        "endmodule\n",
    ]
    if model.init is not None:
        parts.append(f"\ninit\n  {expression_text(model.init)}\nendinit\n")
    parts.append(labels_text(model))
    taken = {chosen.action(state) for state in chosen.reached_states}
    parts.extend(f"\n{_rewards(r, taken)}" for r in model.rewards)
    return "".join(parts)


def labels_text(model: FlatModel) -> str:
    """The model's labels as PRISM text, after a blank line (nothing if it has none)."""
    if not model.labels:
        return ""
    return "\n" + "".join(f'label "{lab.name}" = {expression_text(lab.expr)};\n'
                          for lab in model.labels)


def induced_properties_text(chosen: ChosenStrategy) -> str:
    """The chosen property in its DTMC form, with the MDP's property as a comment.

    :raises ValueError: *chosen* has no property (its ``result`` is None).
    """
    if chosen.result is None:
        raise ValueError("the strategy was not chosen for a property")
    prop = chosen.result.property
    name = f'"{prop.name}": ' if prop.name is not None else ""
    value = chosen.result.value
    optimum = f" = {value!r}" if isinstance(value, float) else ""
    return (f"// On the MDP {chosen.model.source}: {prop.text}{optimum} ({prop.span}).\n"
            "// Its optimum is the value of this property on the induced DTMC:\n"
            f"{_storm_note(prop.formula)}"
            f"{name}{dtmc_property_text(prop.formula, chosen.model)};\n")


def _storm_note(formula: Expr) -> str:
    """For ``W`` and ``R``, which Storm's parser lacks: the ``U`` whose complement they are."""
    if not isinstance(formula, ProbOp):
        return ""
    match formula.path:
        case WeakUntil(left=a, right=b, bound=None):  # a W b = !((a & !b) U (!a & !b))
            path = Until(_and(a, _not(b)), _and(_not(a), _not(b)))
        case Release(left=a, right=b, bound=None):  # a R b = !(!a U !b)
            path = Until(_not(a), _not(b))
        case _:
            return ""
    return f"// (Storm reads no W or R: the value is 1 - P=? [ {path_text(path)} ])\n"


def _not(expr: Expr) -> Expr:
    return Unary("!", expr)


def _and(left: Expr, right: Expr) -> Expr:
    return Binary("&", left, right)


def dtmc_property_text(formula: Expr, model: FlatModel) -> str:
    """``P=? [ path ]``, ``R{...}=? [ path ]`` or ``T=? [ F phi ]`` for a P, R or T
    operator of the MDP."""
    match formula:
        case ProbOp(path=path):
            return f"P=? [ {path_text(path)} ]"
        case RewardOp(reward=reward, path=path) if reward == STEPS_REWARD:
            return f"T=? [ {reward_path_text(path)} ]"  # Storm's expected steps
        case RewardOp(reward=reward, path=path):
            return f"R{_reward_ref(reward, model)}=? [ {reward_path_text(path)} ]"
    raise ValueError("only a P or R operator has a DTMC form")


def _reward_ref(reward: str | int | None, model: FlatModel) -> str:
    """``{"name"}`` (also for a structure given by index, if it has a name: Storm reads
    no ``R{k}``), ``{k}`` (1-based, as PRISM writes it), or nothing for the first."""
    if isinstance(reward, int):
        name = model.rewards[reward].name
        reward = name if name is not None else reward
    if reward is None:
        return ""
    return f'{{"{reward}"}}' if isinstance(reward, str) else f"{{{reward + 1}}}"


def _header(chosen: ChosenStrategy) -> str:
    if chosen.result is None:
        whose = chosen.about
    else:
        prop = chosen.result.property
        whose = f"an optimal strategy of {prop.text} ({prop.span})"
    return (f"// The DTMC that {whose}\n"
            f"// induces on {chosen.model.source}, exported by veribattery: one command per\n"
            "// state reachable under the strategy, guarded by the state's valuation and\n"
            "// labelled by the action taken there.\n\n")


def _declaration(variable: Variable, with_init: bool) -> str:
    kind = "bool" if variable.is_bool else f"[{variable.low}..{variable.high}]"
    value = bool(variable.init) if variable.is_bool else variable.init
    init = f" init {value_text(value)}" if with_init else ""
    return f"{variable.name} : {kind}{init};"


def _commands(chosen: ChosenStrategy) -> Iterator[str]:
    """One command per reachable state that had a choice in the MDP."""
    mdp = chosen.mdp
    dead = mdp.labels.get("deadlock")
    rows = mdp.transitions
    for state in chosen.reached_states:
        if dead is not None and dead[state]:
            continue
        row = int(chosen.strategy.choices[state])
        start, end = int(rows.indptr[row]), int(rows.indptr[row + 1])
        targets = [(int(t), float(p)) for t, p in
                   zip(rows.indices[start:end], rows.data[start:end], strict=True) if p > 0]
        yield (f"[{chosen.action(state)}] {guard_text(chosen.valuation(state))} -> "
               f"{distribution_text(chosen.valuation, state, targets)};")


def _rewards(structure: RewardStruct, taken: set[str]) -> str:
    """A reward structure; an item of an action the strategy never takes is kept as a
    comment (Storm refuses a reward of an action no command has)."""
    name = f' "{structure.name}"' if structure.name is not None else ""
    items = "".join(f"  {_reward_item(item, taken)}\n" for item in structure.items)
    if all(_untaken(item, taken) for item in structure.items):  # Storm wants an item
        items += "  true : 0;  // no item applies under the strategy\n"
    return f"rewards{name}\n{items}endrewards\n"


def _reward_item(item: RewardItem, taken: set[str]) -> str:
    action = f"[{item.action or ''}] " if item.is_transition else ""
    text = f"{action}{expression_text(item.guard)} : {expression_text(item.value)};"
    return f"// {text}  (never taken under the strategy)" if _untaken(item, taken) else text


def _untaken(item: RewardItem, taken: set[str]) -> bool:
    return item.is_transition and (item.action or "") not in taken
