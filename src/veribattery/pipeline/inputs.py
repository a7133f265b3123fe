"""What a caller hands the pipeline, checked before any work: the model and the properties
are parsed ones, and every constant given a value is declared somewhere.

A notebook passes what it has at hand (PRISM text, one property, the parsed file); the
loop over the properties would otherwise fail deep inside with an ``AttributeError``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import PurePath

from veribattery.errors import ArgumentError, PrismSemanticError
from veribattery.lang import FlatModel, Model, PropertiesFile, Property, undefined_constants
from veribattery.lang.constants import require_constants
from veribattery.lang.parser import names_a_file

__all__ = ["parsed_model", "parsed_properties", "reject_unknown_constants"]


def parsed_model(model: object) -> Model:
    """*model*, if it is a parsed (not yet flattened) model.

    :raises ArgumentError: for a file's name or text, or a flattened model, with the call
        that gives what is wanted.
    """
    if isinstance(model, Model):
        return model
    if isinstance(model, FlatModel):
        fix = "the Model it was flattened from: constants= gives the values"
    elif isinstance(model, str) and not names_a_file(model):
        fix = "veribattery.parse_model(text)"
    else:
        named = str(model) if isinstance(model, str | PurePath) else "model.pm"
        fix = f"veribattery.parse_model(Path({named!r}))"
    raise ArgumentError.wrong_kind("model", model, "a parsed Model", fix)


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
    :raises ArgumentError: for *constants* that are no mapping of names to values.
    """
    require_constants(constants)
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
