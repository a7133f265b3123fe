"""The AST's nodes: frozen, slotted standard dataclasses that pickle (sweep workers
receive parsed programs) and leave their spans out of comparison."""

from __future__ import annotations

import copy
import dataclasses
import pickle
from dataclasses import FrozenInstanceError

import pytest

from tests.lang.helpers import tree
from veribattery.errors import NO_SPAN, Span
from veribattery.lang import nodes, parse_model

NODE_CLASSES = [obj for obj in vars(nodes).values()
                if isinstance(obj, type) and dataclasses.is_dataclass(obj)
                and obj.__module__.startswith(f"{nodes.__name__}.")]

MODEL = ("dtmc\nconst double p = 0.25;\nmodule m\n x : [0..2] init 0;\n"
         " [a] x=0 -> p:(x'=1) + 1-p:(x'=2);\n [] x>0 -> true;\nendmodule\n"
         "rewards \"r\" x=1 : 2.5; endrewards\n")


def test_every_node_is_a_frozen_slotted_dataclass() -> None:
    assert len(NODE_CLASSES) == 55  # the case is real: every node class was found
    for cls in [*NODE_CLASSES, Span]:
        params = cls.__dataclass_params__  # type: ignore[attr-defined]
        assert params.frozen and params.eq, cls
        assert "__slots__" in vars(cls) and "__dict__" not in vars(cls), cls


@pytest.mark.parametrize("name", ["value", "span"])
def test_a_node_cannot_be_changed(name: str) -> None:
    literal = nodes.IntLit(3)
    with pytest.raises(FrozenInstanceError, match=f"cannot assign to field '{name}'"):
        setattr(literal, name, 4)
    with pytest.raises(FrozenInstanceError, match=f"cannot delete field '{name}'"):
        delattr(literal, name)
    assert literal.value == 3


def test_a_parsed_program_survives_pickling_as_sweep_workers_need() -> None:
    model = parse_model(MODEL)
    for again in (pickle.loads(pickle.dumps(model)), copy.deepcopy(model)):
        assert again == model and tree(again) == tree(model) and hash(again) == hash(model)
        command = again.modules[0].commands[0]  # type: ignore[union-attr]
        assert command.guard.span == Span(5, 6, "<string>")  # spans survive, uncompared


def test_spans_are_not_compared_and_default_to_one_shared_span() -> None:
    assert nodes.IntLit(1).span is NO_SPAN
    here, there = Span(1, 1, "a.pm"), Span(9, 4, "b.pm")
    assert nodes.IntLit(1, here) == nodes.IntLit(1, there)
    assert hash(nodes.IntLit(1, here)) == hash(nodes.IntLit(1, there))
    assert nodes.IntLit(1, here) != nodes.IntLit(2, here)
