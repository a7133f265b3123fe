"""The precompiled method bodies behind :func:`veribattery._record.record`, one per arity.

Generated once and not edited since: they are compiled with this module (and cached
in its ``.pyc``), so defining a record compiles nothing. :func:`~veribattery._record.record`
takes a template's code object and renames its parameters (``__init__``) or its
attribute names (``__eq__``, ``__hash__``) to the class's fields with
:meth:`types.CodeType.replace`. The bodies are those ``dataclasses`` generates for a
frozen class: ``__init__`` stores argument *k* through setter ``s<k>`` (the field's
slot, a closure cell bound per class); ``__eq__`` compares the tuples of fields
``f0 .. f<k-1>`` of two instances of the same class; ``__hash__`` hashes that tuple.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["EQ_TEMPLATES", "HASH_TEMPLATES", "INIT_TEMPLATES"]

_Setter = Callable[[Any, Any], None]


def _init_templates(s0: _Setter, s1: _Setter, s2: _Setter, s3: _Setter, s4: _Setter, s5: _Setter,
                    s6: _Setter, s7: _Setter, s8: _Setter, s9: _Setter, s10: _Setter, s11: _Setter
                    ) -> tuple[Callable[..., None], ...]:
    """``__init__`` for 0 to 12 fields."""

    def init0(self: Any) -> None:
        pass

    def init1(self: Any, a0: Any) -> None:
        s0(self, a0)

    def init2(self: Any, a0: Any, a1: Any) -> None:
        s0(self, a0)
        s1(self, a1)

    def init3(self: Any, a0: Any, a1: Any, a2: Any) -> None:
        s0(self, a0)
        s1(self, a1)
        s2(self, a2)

    def init4(self: Any, a0: Any, a1: Any, a2: Any, a3: Any) -> None:
        s0(self, a0)
        s1(self, a1)
        s2(self, a2)
        s3(self, a3)

    def init5(self: Any, a0: Any, a1: Any, a2: Any, a3: Any, a4: Any) -> None:
        s0(self, a0)
        s1(self, a1)
        s2(self, a2)
        s3(self, a3)
        s4(self, a4)

    def init6(self: Any, a0: Any, a1: Any, a2: Any, a3: Any, a4: Any, a5: Any) -> None:
        s0(self, a0)
        s1(self, a1)
        s2(self, a2)
        s3(self, a3)
        s4(self, a4)
        s5(self, a5)

    def init7(self: Any, a0: Any, a1: Any, a2: Any, a3: Any, a4: Any, a5: Any, a6: Any) -> None:
        s0(self, a0)
        s1(self, a1)
        s2(self, a2)
        s3(self, a3)
        s4(self, a4)
        s5(self, a5)
        s6(self, a6)

    def init8(self: Any, a0: Any, a1: Any, a2: Any, a3: Any, a4: Any, a5: Any, a6: Any, a7: Any
              ) -> None:
        s0(self, a0)
        s1(self, a1)
        s2(self, a2)
        s3(self, a3)
        s4(self, a4)
        s5(self, a5)
        s6(self, a6)
        s7(self, a7)

    def init9(self: Any, a0: Any, a1: Any, a2: Any, a3: Any, a4: Any, a5: Any, a6: Any, a7: Any,
              a8: Any) -> None:
        s0(self, a0)
        s1(self, a1)
        s2(self, a2)
        s3(self, a3)
        s4(self, a4)
        s5(self, a5)
        s6(self, a6)
        s7(self, a7)
        s8(self, a8)

    def init10(self: Any, a0: Any, a1: Any, a2: Any, a3: Any, a4: Any, a5: Any, a6: Any, a7: Any,
               a8: Any, a9: Any) -> None:
        s0(self, a0)
        s1(self, a1)
        s2(self, a2)
        s3(self, a3)
        s4(self, a4)
        s5(self, a5)
        s6(self, a6)
        s7(self, a7)
        s8(self, a8)
        s9(self, a9)

    def init11(self: Any, a0: Any, a1: Any, a2: Any, a3: Any, a4: Any, a5: Any, a6: Any, a7: Any,
               a8: Any, a9: Any, a10: Any) -> None:
        s0(self, a0)
        s1(self, a1)
        s2(self, a2)
        s3(self, a3)
        s4(self, a4)
        s5(self, a5)
        s6(self, a6)
        s7(self, a7)
        s8(self, a8)
        s9(self, a9)
        s10(self, a10)

    def init12(self: Any, a0: Any, a1: Any, a2: Any, a3: Any, a4: Any, a5: Any, a6: Any, a7: Any,
               a8: Any, a9: Any, a10: Any, a11: Any) -> None:
        s0(self, a0)
        s1(self, a1)
        s2(self, a2)
        s3(self, a3)
        s4(self, a4)
        s5(self, a5)
        s6(self, a6)
        s7(self, a7)
        s8(self, a8)
        s9(self, a9)
        s10(self, a10)
        s11(self, a11)

    return (init0, init1, init2, init3, init4, init5, init6, init7, init8, init9, init10, init11,
            init12)


def _eq_templates() -> tuple[Callable[[Any, Any], Any], ...]:
    """``__eq__`` on fields ``f0 .. f<k-1>``, for 0 to 12 fields."""

    def eq0(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return True
        return NotImplemented

    def eq1(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return (self.f0,) == (other.f0,)
        return NotImplemented

    def eq2(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1)
                    == (other.f0, other.f1))
        return NotImplemented

    def eq3(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1, self.f2)
                    == (other.f0, other.f1, other.f2))
        return NotImplemented

    def eq4(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1, self.f2, self.f3)
                    == (other.f0, other.f1, other.f2, other.f3))
        return NotImplemented

    def eq5(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1, self.f2, self.f3, self.f4)
                    == (other.f0, other.f1, other.f2, other.f3, other.f4))
        return NotImplemented

    def eq6(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5)
                    == (other.f0, other.f1, other.f2, other.f3, other.f4, other.f5))
        return NotImplemented

    def eq7(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6)
                    == (other.f0, other.f1, other.f2, other.f3, other.f4, other.f5, other.f6))
        return NotImplemented

    def eq8(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6, self.f7)
                    == (other.f0, other.f1, other.f2, other.f3, other.f4, other.f5, other.f6,
                        other.f7))
        return NotImplemented

    def eq9(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6, self.f7, self.f8
                     )
                    == (other.f0, other.f1, other.f2, other.f3, other.f4, other.f5, other.f6,
                        other.f7, other.f8))
        return NotImplemented

    def eq10(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6, self.f7,
                     self.f8, self.f9)
                    == (other.f0, other.f1, other.f2, other.f3, other.f4, other.f5, other.f6,
                        other.f7, other.f8, other.f9))
        return NotImplemented

    def eq11(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6, self.f7,
                     self.f8, self.f9, self.f10)
                    == (other.f0, other.f1, other.f2, other.f3, other.f4, other.f5, other.f6,
                        other.f7, other.f8, other.f9, other.f10))
        return NotImplemented

    def eq12(self: Any, other: Any) -> Any:
        if other.__class__ is self.__class__:
            return ((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6, self.f7,
                     self.f8, self.f9, self.f10, self.f11)
                    == (other.f0, other.f1, other.f2, other.f3, other.f4, other.f5, other.f6,
                        other.f7, other.f8, other.f9, other.f10, other.f11))
        return NotImplemented

    return (eq0, eq1, eq2, eq3, eq4, eq5, eq6, eq7, eq8, eq9, eq10, eq11, eq12)


def _hash_templates() -> tuple[Callable[[Any], int], ...]:
    """``__hash__`` of fields ``f0 .. f<k-1>``, for 0 to 12 fields."""

    def hash0(self: Any) -> int:
        return hash(())

    def hash1(self: Any) -> int:
        return hash((self.f0,))

    def hash2(self: Any) -> int:
        return hash((self.f0, self.f1))

    def hash3(self: Any) -> int:
        return hash((self.f0, self.f1, self.f2))

    def hash4(self: Any) -> int:
        return hash((self.f0, self.f1, self.f2, self.f3))

    def hash5(self: Any) -> int:
        return hash((self.f0, self.f1, self.f2, self.f3, self.f4))

    def hash6(self: Any) -> int:
        return hash((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5))

    def hash7(self: Any) -> int:
        return hash((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6))

    def hash8(self: Any) -> int:
        return hash((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6, self.f7))

    def hash9(self: Any) -> int:
        return hash((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6, self.f7, self.f8
                     ))

    def hash10(self: Any) -> int:
        return hash((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6, self.f7,
                     self.f8, self.f9))

    def hash11(self: Any) -> int:
        return hash((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6, self.f7,
                     self.f8, self.f9, self.f10))

    def hash12(self: Any) -> int:
        return hash((self.f0, self.f1, self.f2, self.f3, self.f4, self.f5, self.f6, self.f7,
                     self.f8, self.f9, self.f10, self.f11))

    return (hash0, hash1, hash2, hash3, hash4, hash5, hash6, hash7, hash8, hash9, hash10, hash11,
            hash12)


def _unset(instance: Any, value: Any) -> None:  # pragma: no cover -- replaced per class
    raise AssertionError("a template setter was called")


#: ``__init__``, ``__eq__`` and ``__hash__`` code for 0 to 12 fields (index = field count).
INIT_TEMPLATES = tuple(f.__code__ for f in _init_templates(*[_unset] * 12))
EQ_TEMPLATES = tuple(f.__code__ for f in _eq_templates())
HASH_TEMPLATES = tuple(f.__code__ for f in _hash_templates())
