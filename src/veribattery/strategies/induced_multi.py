"""The DTMC a ``multi(...)`` witness strategy induces, as a PRISM model and properties.

The model keeps the MDP's variables and adds the memory's
(:mod:`~veribattery.strategies.randomised`), so that labels and properties read as
on the MDP. Per memory state reached, one unlabelled command guarded by its
valuation carries the whole mixed distribution: each successor with the sum over the
moves of ``p(move) * P(choice, successor)``. A DTMC cannot weight commands, so the
mixture is one command, and its action rewards become, per memory state, the
*expected* reward of its step (the state's reward plus its choices' action rewards,
weighted by their probabilities) as a state reward. That preserves the expected
total reward ``C`` and the reward until a target ``F`` -- both sum the reward of
each step taken, and by linearity of expectation the expected reward of a step is
the expected reward of its choice -- but not ``I=k``. Every reward structure of the
model is written so, in the same order (``R{k}`` keeps its meaning), with its name.

The properties file holds each objective in its DTMC form (``P=? [ F phi ]``,
``R{"r"}=? [ C ]``; a state-formula objective ``P [ phi ]`` as ``P=? [ false U
phi ]``, which holds exactly where *phi* does), and, as comments, what it had to
be and its value on the chain as veribattery found it, certified.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from veribattery.lang.nodes import ProbOp, RewardOp, Variable
from veribattery.strategies.induced import dtmc_property_text, labels_text
from veribattery.strategies.randomised import ChosenMulti
from veribattery.strategies.valuation_text import distribution_text, guard_text, value_text

__all__ = ["induced_multi_model_text", "induced_multi_properties_text"]


def induced_multi_model_text(chosen: ChosenMulti) -> str:
    """The induced DTMC as a PRISM ``dtmc`` model (see the module's description)."""
    model = chosen.model
    start = chosen.valuation(chosen.strategy.initial)
    parts = [
        _header(chosen),
        "dtmc\n\nmodule strategy\n",
        *(f"  {_declaration(v, start[v.name])}\n" for v in model.variables),
        *(f"  {name} : bool init {value_text(start[name])};\n" for name in chosen.visited),
        *([f"  {chosen.mode} : [0..1] init 0;\n"] if chosen.mode is not None else []),
        "\n",
        *(f"  {command}\n" for command in _commands(chosen)),
        "endmodule\n",
        labels_text(model),
    ]
    parts.extend(f"\n{_rewards(chosen, index)}" for index in range(len(chosen.mdp.rewards)))
    return "".join(parts)


def induced_multi_properties_text(chosen: ChosenMulti) -> str:
    """Each objective of the ``multi(...)`` property in its DTMC form, with what it had
    to be and its value on the chain as comments."""
    prop = chosen.result.property
    value = chosen.result.value
    answer = ("true" if value else "false") if isinstance(value, bool) else repr(value)
    lines = [f"// On the MDP {chosen.model.source}: {prop.text} = {answer} "
             f"({prop.span}).\n",
             "// Its objectives on the DTMC the witness strategy induces (each checked by "
             "veribattery:\n// met, or the optimum, within the linear programme's "
             "tolerance):\n"]
    objectives = [op for op in getattr(prop.formula, "objectives", ())
                  if isinstance(op, ProbOp | RewardOp)]
    for op, found in zip(objectives, chosen.strategy.values, strict=True):
        lines.append(f"\n// {found.text}: must be {found.requirement}; here {found.value!r} "
                     f"(certified in [{found.lower!r}, {found.upper!r}])\n")
        lines.append(f"{dtmc_property_text(_named(op), chosen.model)};\n")
    return "".join(lines)


def _named(op: ProbOp | RewardOp) -> ProbOp | RewardOp:
    """``R`` (the first structure) as ``R{"name"}``, or ``R{1}`` if it has none: Storm
    refuses a plain ``R`` when the model has several structures, as this one may."""
    if isinstance(op, RewardOp) and op.reward is None:
        return replace(op, reward=0)
    return op


def _header(chosen: ChosenMulti) -> str:
    prop = chosen.result.property
    memory = ", ".join([*chosen.visited, *([chosen.mode] if chosen.mode else [])])
    return (f"// The DTMC that a randomised strategy attaining {prop.text} ({prop.span})\n"
            f"// induces on {chosen.model.source}, exported by veribattery: one command per\n"
            "// memory state reached, guarded by its valuation, with the strategy's mixed\n"
            "// distribution; memory variables: "
            f"{memory or 'none'}. Rewards are each step's expected\n"
            "// reward as a state reward (right for C and F rewards, not for I=k).\n\n")


def _declaration(variable: Variable, value: int | bool) -> str:
    kind = "bool" if variable.is_bool else f"[{variable.low}..{variable.high}]"
    return f"{variable.name} : {kind} init {value_text(value)};"


def _commands(chosen: ChosenMulti) -> list[str]:
    """One command per memory state whose MDP state had a choice (a deadlock keeps
    its implicit self-loop, as in :mod:`~veribattery.strategies.induced`)."""
    dead = chosen.mdp.labels.get("deadlock")
    chain = chosen.strategy.chain
    commands = []
    for node in chosen.nodes:
        if dead is not None and dead[int(chosen.strategy.node_state[node])]:
            continue
        start, end = int(chain.indptr[node]), int(chain.indptr[node + 1])
        targets = [(int(t), float(p)) for t, p in
                   zip(chain.indices[start:end], chain.data[start:end], strict=True) if p > 0]
        commands.append(f"[] {guard_text(chosen.valuation(node))} -> "
                        f"{distribution_text(chosen.valuation, node, targets)};")
    return commands


def _rewards(chosen: ChosenMulti, index: int) -> str:
    """Reward structure *index* as the expected reward of each memory state's step."""
    structure = chosen.mdp.rewards[index]
    per_node = chosen.strategy.expected_rewards(structure.per_choice(chosen.mdp))
    name = f' "{structure.name}"' if structure.name is not None else ""
    items = "".join(f"  {guard_text(chosen.valuation(int(node)))} : {float(per_node[node])!r};\n"
                    for node in np.flatnonzero(per_node != 0))
    items = items or "  true : 0;\n"  # Storm wants an item
    return f"rewards{name}\n{items}endrewards\n"
