"""What a caller hands the pipeline, checked before any work: the properties are parsed
ones, and every constant given a value is declared somewhere.

A notebook passes what it has at hand (PRISM text, one property, the parsed file); the
loop over the properties would otherwise fail deep inside with an ``AttributeError``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from veribattery.errors import ArgumentError, PrismSemanticError
from veribattery.lang import Model, PropertiesFile, Property, undefined_constants

__all__ = ["parsed_properties", "reject_unknown_constants"]


def parsed_properties(properties: object) -> tuple[Property, ...]:
    """*properties* as a tuple, if it is a sequence of parsed properties.

    :raises ArgumentError: for text, one property or a whole properties file, with the
        call that gives what is wanted.
    """
    if isinstance(properties, str):
        fix = f"veribattery.parse_properties({_cut(properties)!r}).properties"
        raise ArgumentError(f"properties: parsed properties are needed, not text: give {fix}")
    if isinstance(properties, Property):
        raise ArgumentError("properties: a sequence of properties is needed, not one "
                            "Property: give (prop,)")
    if isinstance(properties, PropertiesFile):
        raise ArgumentError("properties: a sequence of properties is needed, not a "
                            "PropertiesFile: give props.properties, and props_file=props "
                            "for its constants and labels")
    chosen = tuple(properties) if isinstance(properties, Sequence) else None
    if chosen is None or not all(isinstance(p, Property) for p in chosen):
        raise ArgumentError("properties: a sequence of parsed properties is needed "
                            "(veribattery.parse_properties(text).properties), not "
                            f"{_cut(repr(properties))}")
    return chosen


def reject_unknown_constants(
    model: Model, props: PropertiesFile | None, constants: Mapping[str, object]
) -> None:
    """A value for a constant that neither *model* nor *props* declares is a typo: say
    so, don't ignore it.

    :raises PrismSemanticError: naming the unknown constants and the undefined ones.
    """
    declared = {c.name for c in model.constants}
    declared |= {c.name for c in props.constants} if props is not None else set()
    unknown = sorted(set(constants) - declared)
    if unknown:
        hint = ", ".join(undefined_constants(model, props)) or "none"
        raise PrismSemanticError(
            f"constant{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}: declared "
            "neither in the model nor in its properties, but given a value (by --const, "
            f"or constants= from Python); the undefined constants are: {hint}")


def _cut(text: str, keep: int = 60) -> str:
    return text if len(text) <= keep else text[:keep] + "…"
