"""``@record``: ``@dataclass(frozen=True, slots=True)`` without compiling source at import.

The stdlib decorator writes the source of six methods per class (``__init__``,
``__repr__``, ``__eq__``, ``__hash__``, ``__setattr__``, ``__delattr__``) and compiles
each with ``exec``: about a millisecond per class, and a ``prism`` check defines about a
hundred such classes before it reads its model (the AST alone has 49). :func:`record`
makes the same class from code compiled once, with this module:

- ``dataclasses.dataclass(init=False, repr=False, eq=False, slots=True)`` collects the
  fields and makes the slotted class (that part compiles nothing), so
  ``dataclasses.fields``, ``replace``, ``asdict``, ``is_dataclass`` and ``match`` work
  as on any dataclass;
- ``__init__``, ``__eq__`` and ``__hash__`` are precompiled templates for the number of
  fields (:mod:`veribattery._record_code`) with their parameter or attribute names
  renamed to the fields (:meth:`types.CodeType.replace`): the bodies, and so the speed,
  of the generated ones; ``__init__`` stores each argument through the field's slot
  descriptor, with the field defaults as its defaults;
- repr, immutability and pickling are closures, with the stdlib's semantics: repr
  ``Name(field=value, ...)``; assigning or deleting an attribute raises
  :class:`dataclasses.FrozenInstanceError`; the pickled state is the list of field
  values (``__getstate__``/``__setstate__``, as for a frozen slotted dataclass).

A class outside that pattern (a base class, ``default_factory``, ``init=False``,
``kw_only``, ``ClassVar``/``InitVar``, ``__post_init__``, its own ``__eq__`` ..., more
than :data:`MAX_FIELDS` fields, no docstring) is handed to
``dataclass(frozen=True, slots=True)`` unchanged: ``@record`` is never wrong, at worst
as slow as the stdlib.
"""

from __future__ import annotations

import builtins
import dataclasses
import reprlib
from collections.abc import Callable
from operator import attrgetter
from types import CellType, CodeType, FunctionType
from typing import Any, TypeVar, dataclass_transform

from veribattery._record_code import EQ_TEMPLATES, HASH_TEMPLATES, INIT_TEMPLATES

__all__ = ["MAX_FIELDS", "record"]

_T = TypeVar("_T")
#: What the templates' code runs in (they only read builtins: ``hash``, ``NotImplemented``).
_TEMPLATE_GLOBALS: dict[str, Any] = {"__builtins__": builtins}
#: Classes with more fields than this go to ``dataclasses.dataclass``.
MAX_FIELDS = len(INIT_TEMPLATES) - 1
#: Methods :func:`record` writes; a class defining one itself goes to the stdlib.
_GENERATED = frozenset({
    "__init__", "__repr__", "__eq__", "__hash__", "__setattr__", "__delattr__",
    "__getstate__", "__setstate__", "__post_init__",
})


@dataclass_transform(frozen_default=True, field_specifiers=(dataclasses.field,))
def record(cls: type[_T]) -> type[_T]:
    """The class as ``@dataclass(frozen=True, slots=True)`` would make it (see the module).

    :param cls: a class with annotated fields, plain defaults or ``field(default=...,
        compare=..., hash=..., repr=...)``, and a docstring.
    """
    if not _covered(cls):
        return dataclasses.dataclass(frozen=True, slots=True)(cls)
    made = dataclasses.dataclass(init=False, repr=False, eq=False, slots=True)(cls)
    fields = dataclasses.fields(made)  # type: ignore[arg-type]
    for name, method in _methods(made, fields).items():
        method.__qualname__ = f"{made.__qualname__}.{name}"
        setattr(made, name, method)
    params = made.__dataclass_params__  # type: ignore[attr-defined]
    params.init = params.repr = params.eq = params.frozen = True
    return made


def _covered(cls: type) -> bool:
    """Whether *cls* is a plain record :func:`record` reproduces exactly."""
    own = vars(cls)
    annotations = own.get("__annotations__", {})
    if (cls.__bases__ != (object,) or not own.get("__doc__") or _GENERATED & own.keys()
            or len(annotations) > MAX_FIELDS or "self" in annotations):
        return False
    for name, annotation in annotations.items():
        if any(word in str(annotation) for word in ("ClassVar", "InitVar", "KW_ONLY")):
            return False
        default = own.get(name)
        if isinstance(default, dataclasses.Field) and (
                default.default_factory is not dataclasses.MISSING or not default.init
                or default.kw_only is True):
            return False
    return True


def _methods(cls: type, fields: tuple[dataclasses.Field[Any], ...]) -> dict[str, Any]:
    """The generated methods of *cls*, by name."""
    names = tuple(f.name for f in fields)
    compared = tuple(f.name for f in fields if f.compare)
    hashed = tuple(f.name for f in fields if (f.compare if f.hash is None else f.hash))
    shown = tuple(f.name for f in fields if f.repr)
    return {
        "__init__": _init(cls, fields),
        "__repr__": _repr(shown, _values(shown)),
        "__eq__": _renamed(EQ_TEMPLATES, "__eq__", compared),
        "__hash__": _renamed(HASH_TEMPLATES, "__hash__", hashed),
        "__setattr__": _frozen_setattr(cls, frozenset(names)),
        "__delattr__": _frozen_delattr(cls, frozenset(names)),
        "__getstate__": _getstate(_values(names)),
        "__setstate__": _setstate(cls, names),
    }


def _init(cls: type, fields: tuple[dataclasses.Field[Any], ...]) -> FunctionType:
    """``__init__(self, <fields>)``: the template for ``len(fields)``, renamed and bound."""
    names = tuple(f.name for f in fields)
    code = INIT_TEMPLATES[len(names)].replace(co_varnames=("self", *names), co_name="__init__")
    setters = {f"s{i}": vars(cls)[name].__set__ for i, name in enumerate(names)}
    closure = tuple(CellType(setters[free]) for free in code.co_freevars)
    defaults = tuple(f.default for f in fields if f.default is not dataclasses.MISSING)
    init = FunctionType(code, _TEMPLATE_GLOBALS, "__init__", defaults or None, closure)
    init.__annotations__ = {**{f.name: f.type for f in fields}, "return": None}
    return init


def _values(names: tuple[str, ...]) -> Callable[[Any], tuple[Any, ...]]:
    """A function returning the tuple of the fields *names* of an instance."""
    if len(names) >= 2:
        return attrgetter(*names)
    if names:
        get = attrgetter(names[0])
        return lambda instance: (get(instance),)
    return lambda instance: ()


def _repr(names: tuple[str, ...], values: Callable[[Any], tuple[Any, ...]]) -> Any:
    @reprlib.recursive_repr()
    def __repr__(self: Any) -> str:
        pairs = zip(names, values(self), strict=True)
        shown = ", ".join(f"{name}={value!r}" for name, value in pairs)
        return f"{self.__class__.__qualname__}({shown})"

    return __repr__


def _renamed(templates: tuple[CodeType, ...], name: str, fields: tuple[str, ...]) -> Any:
    """The template for ``len(fields)`` reading the attributes *fields* (not ``f0`` ...)."""
    code = templates[len(fields)]
    renamed = {f"f{i}": field for i, field in enumerate(fields)}
    names = tuple(renamed.get(used, used) for used in code.co_names)
    return FunctionType(code.replace(co_names=names, co_name=name), _TEMPLATE_GLOBALS, name)


def _frozen_setattr(cls: type, names: frozenset[str]) -> Callable[[Any, str, Any], None]:
    def __setattr__(self: Any, name: str, value: Any) -> None:
        if type(self) is cls or name in names:
            raise dataclasses.FrozenInstanceError(f"cannot assign to field {name!r}")
        object.__setattr__(self, name, value)

    return __setattr__


def _frozen_delattr(cls: type, names: frozenset[str]) -> Callable[[Any, str], None]:
    def __delattr__(self: Any, name: str) -> None:
        if type(self) is cls or name in names:
            raise dataclasses.FrozenInstanceError(f"cannot delete field {name!r}")
        object.__delattr__(self, name)

    return __delattr__


def _getstate(values: Callable[[Any], tuple[Any, ...]]) -> Callable[[Any], list[Any]]:
    def __getstate__(self: Any) -> list[Any]:
        return list(values(self))

    return __getstate__


def _setstate(cls: type, names: tuple[str, ...]) -> Callable[[Any, list[Any]], None]:
    setters = tuple(vars(cls)[name].__set__ for name in names)

    def __setstate__(self: Any, state: list[Any]) -> None:
        for set_field, value in zip(setters, state, strict=False):
            set_field(self, value)

    return __setstate__
