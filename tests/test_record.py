"""``@record`` makes the class ``@dataclass(frozen=True, slots=True)`` makes, compiling nothing.

Every record class of the package (the AST nodes first: sweep workers pickle parsed
programs) is compared with its stdlib twin, built from the same annotations and
fields, on instances that differ in each field in turn.
"""

from __future__ import annotations

import copy
import dataclasses
import importlib
import inspect
import math
import pickle
import pkgutil
import subprocess
import sys
from dataclasses import FrozenInstanceError, dataclass, field
from typing import Any

import pytest

import veribattery
from veribattery._record import MAX_FIELDS, record
from veribattery.errors import NO_SPAN, Span
from veribattery.lang import nodes, parse_model


def _record_classes() -> list[type]:
    """Every class of the package made by ``@record`` (its ``__init__`` is a template)."""
    found = []
    for info in pkgutil.walk_packages(veribattery.__path__, "veribattery."):
        if info.name.startswith(("veribattery.cli", "veribattery.sweep", "veribattery.phm",
                                 "veribattery.analyses")):
            continue  # they import optional libraries; no records live there
        module = importlib.import_module(info.name)
        found += [obj for obj in vars(module).values()
                  if isinstance(obj, type) and obj.__module__ == module.__name__
                  and dataclasses.is_dataclass(obj)
                  and obj.__init__.__code__.co_filename.endswith("_record_code.py")]
    return found


RECORDS = _record_classes()


def _twin(cls: type) -> type:
    """*cls* as the stdlib makes it: same name, fields, defaults and other members."""
    members: dict[str, Any] = {
        name: value for name, value in vars(cls).items()
        if name not in {*cls.__slots__, "__slots__", "__dict__", "__weakref__",
                        "__dataclass_fields__", "__dataclass_params__", "__match_args__",
                        "__init__", "__repr__", "__eq__", "__hash__", "__setattr__",
                        "__delattr__", "__getstate__", "__setstate__"}
    }
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            members[f.name] = field(default=f.default, compare=f.compare, hash=f.hash,
                                    repr=f.repr)
    members["__annotations__"] = {f.name: f.type for f in dataclasses.fields(cls)}
    twin = type(cls.__name__, (), members)
    twin.__qualname__ = cls.__qualname__
    made: type = dataclass(frozen=True, slots=True)(twin)
    return made


def _samples(cls: type) -> list[dict[str, Any]]:
    """Field values: a base instance, then each field changed in turn (NaN included)."""
    names = [f.name for f in dataclasses.fields(cls)]
    base = {name: ("value", i) for i, name in enumerate(names)}
    variants = [base]
    for name in names:
        variants.append({**base, name: ("other", name)})
        variants.append({**base, name: math.nan})
    return variants


def test_the_package_has_records_and_every_node_is_one() -> None:
    node_classes = [obj for obj in vars(nodes).values()
                    if isinstance(obj, type) and dataclasses.is_dataclass(obj)
                    and obj.__module__.startswith(f"{nodes.__name__}.")]
    assert len(node_classes) == 49
    assert set(node_classes) <= set(RECORDS)
    assert Span in RECORDS


@pytest.mark.parametrize("cls", RECORDS, ids=lambda cls: f"{cls.__module__}.{cls.__name__}")
def test_a_record_behaves_as_its_stdlib_twin(cls: type) -> None:
    twin = _twin(cls)
    assert cls.__slots__ == twin.__slots__
    assert cls.__match_args__ == twin.__match_args__  # type: ignore[attr-defined]
    assert repr(cls.__dataclass_params__) == repr(twin.__dataclass_params__)  # type: ignore[attr-defined]
    assert str(inspect.signature(cls)) == str(inspect.signature(twin))
    assert [(f.name, f.default, f.compare, f.hash, f.repr) for f in dataclasses.fields(cls)] \
        == [(f.name, f.default, f.compare, f.hash, f.repr) for f in dataclasses.fields(twin)]
    samples = _samples(cls)
    made = [cls(**values) for values in samples]
    twins = [twin(**values) for values in samples]
    for a, ta in zip(made, twins, strict=True):
        assert repr(a) == repr(ta)
        assert hash(a) == hash(ta)
        assert dataclasses.asdict(a) == dataclasses.asdict(ta)
        for b, tb in zip(made, twins, strict=True):
            assert (a == b) == (ta == tb) and (a != b) == (ta != tb)
        assert (a == ta) is False  # another class, as between two stdlib dataclasses


@pytest.mark.parametrize("cls", RECORDS, ids=lambda cls: f"{cls.__module__}.{cls.__name__}")
def test_a_record_is_frozen_and_pickles_and_copies_as_a_stdlib_one(cls: type) -> None:
    twin = _twin(cls)
    values = _samples(cls)[0]
    instance, twin_instance = cls(**values), twin(**values)
    assert instance.__getstate__() == twin_instance.__getstate__()  # type: ignore[attr-defined]
    for copied in (pickle.loads(pickle.dumps(instance)), copy.copy(instance),
                   copy.deepcopy(instance)):
        assert type(copied) is cls and copied == instance and repr(copied) == repr(instance)
    for name in values:
        with pytest.raises(FrozenInstanceError, match=f"cannot assign to field '{name}'"):
            setattr(instance, name, 1)
        with pytest.raises(FrozenInstanceError, match=f"cannot delete field '{name}'"):
            delattr(instance, name)
    first = {next(iter(values)): "replaced"}
    changed, twin_changed = dataclasses.replace(instance, **first), twin_instance
    twin_changed = dataclasses.replace(twin_instance, **first)
    assert repr(changed) == repr(twin_changed) and repr(changed).count("replaced") == 1
    assert (changed == instance) == (twin_changed == twin_instance)


def test_a_parsed_program_survives_pickling_as_sweep_workers_need() -> None:
    model = parse_model("dtmc\nconst double p = 0.25;\nmodule m\n x : [0..2] init 0;\n"
                        " [a] x=0 -> p:(x'=1) + 1-p:(x'=2);\n [] x>0 -> true;\nendmodule\n"
                        "rewards \"r\" x=1 : 2.5; endrewards\n")
    again = pickle.loads(pickle.dumps(model))
    assert again == model and repr(again) == repr(model) and hash(again) == hash(model)
    command = again.modules[0].commands[0]  # type: ignore[union-attr]
    assert command.guard.span == Span(5, 6, "<string>")  # spans survive, uncompared


@record
class _Empty:
    """No fields."""


@record
class _One:
    """One field (NaN: a tuple compares an element with itself by identity first)."""

    value: float


@record
class _Wide:
    """As many fields as the largest template."""

    f00: int
    f01: int
    f02: int
    f03: int
    f04: int
    f05: int
    f06: int
    f07: int
    f08: int
    f09: int
    f10: int
    f11: int = 11


def test_edge_arities() -> None:
    assert _Empty() == _Empty() and hash(_Empty()) == hash(()) and repr(_Empty()) == "_Empty()"
    nan = math.nan
    assert _One(nan) == _One(nan) and _One(1.0) != _One(2.0) and hash(_One(3.0)) == hash((3.0,))
    assert _One(float("nan")) != _One(float("nan"))  # two NaN objects: unequal (stdlib too)
    wide = _Wide(*range(11))
    assert wide == _Wide(*range(12)) and wide.f11 == 11 and len(dataclasses.fields(_Wide)) == 12
    assert MAX_FIELDS == 12
    with pytest.raises(TypeError, match=r"_Wide.__init__\(\) missing 1 required positional"):
        _Wide(*range(10))  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="unexpected keyword argument 'nope'"):
        _One(1.0, nope=2)  # type: ignore[call-arg]


@record
class _Factory:
    """Outside the pattern (a default factory): the stdlib makes it."""

    items: tuple[int, ...] = field(default_factory=tuple)


@record
class _Own:
    """Outside the pattern (its own repr): the stdlib makes it and keeps the repr."""

    value: int

    def __repr__(self) -> str:
        return "own"


def test_classes_outside_the_pattern_go_to_the_stdlib() -> None:
    assert _Factory().items == () and _Factory((1,)) == _Factory((1,))
    assert not _Factory.__init__.__code__.co_filename.endswith("_record_code.py")
    assert repr(_Own(1)) == "own" and _Own(1) == _Own(1)
    with pytest.raises(FrozenInstanceError):
        _Own(1).value = 2  # type: ignore[misc]


def test_defining_records_compiles_nothing() -> None:
    # Audit hooks cannot be removed, so the count runs in a fresh interpreter; the
    # stdlib decorator compiles six methods per class (the control).
    script = """
import sys, dataclasses
from veribattery._record import record
counted = []
sys.addaudithook(lambda event, args: counted.append(event) if event == "compile" else None)
for decorate in (record, dataclasses.dataclass(frozen=True, slots=True)):
    before = len(counted)
    for _ in range(3):
        class Node:
            '''A node.'''
            op: str
            left: int
            span: int = dataclasses.field(default=0, compare=False)
        Node = decorate(Node)
        assert Node("+", 1) == Node("+", 1, 5)
    print(len(counted) - before)
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          check=True)
    assert done.stdout.split() == ["0", "18"]


def test_no_span_default_is_shared() -> None:
    assert nodes.IntLit(1).span is NO_SPAN
