"""The one error hierarchy of veribattery: every user-facing error says where it happened."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Span:
    """A 1-based position in a source text; *source* names the file (or ``<string>``)."""

    line: int
    col: int
    source: str = "<string>"

    def __str__(self) -> str:
        return f"{self.source}:{self.line}:{self.col}"


NO_SPAN = Span(0, 0, "")


class VeribatteryError(Exception):
    """Base of every error veribattery reports to a user (the CLI exits 2 on these)."""

    def __init__(self, message: str, span: Span | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.span = span if span is not None and span.line > 0 else None

    def __str__(self) -> str:
        return f"{self.span}: {self.message}" if self.span else self.message


class ArgumentError(VeribatteryError, ValueError):
    """A library function was given an argument it cannot use: a value outside its
    choices, or an object of another kind (PRISM text where a parsed property belongs).
    Also a :class:`ValueError`, which these arguments raised before."""

    @classmethod
    def wrong_kind(cls, what: str, value: object, needed: str, fix: str) -> ArgumentError:
        """The error for *value*, given as *what* where *needed* belongs: it names the
        kind given and the call that gives what is needed (*fix*).

        A notebook hands a stage what it has at hand (a file name, a dict, the previous
        stage's input); without this the stage fails deep inside with an
        ``AttributeError`` that names neither the argument nor the remedy.
        """
        shown = repr(value)
        shown = shown if len(shown) <= 60 else shown[:60] + "…"
        return cls(f"{what}: {needed} is needed, not {type(value).__name__} {shown}: "
                   f"give {fix}")


class ConfigError(VeribatteryError):
    """A mission config is malformed: YAML syntax, unknown key, wrong type or range."""


class OptionError(VeribatteryError):
    """A command-line option's value is unusable: an output path, a file type, a number."""


class RenderError(VeribatteryError):
    """A template could not be rendered from a config."""


class PrismSyntaxError(VeribatteryError):
    """PRISM model or property text does not parse."""


class PrismSemanticError(VeribatteryError):
    """PRISM text parses but is not a valid model or property (types, names, ranges)."""


class ModelError(VeribatteryError):
    """The state space cannot be built: out-of-range update, bad probabilities."""


class ModelTooLarge(ModelError):
    """The state space would not fit in the memory available: the builder stops while
    it still can, and says how many states it found and how much more it needed."""


class CheckError(VeribatteryError):
    """A property cannot be checked on a built model."""


class UndefinedResult(CheckError):
    """A property has no value on this model: a condition that is never met, or an
    operator the exact engine does not compute. A caller checking a fixed set of
    properties (the mission's defaults) may report it as undefined (NaN) with a
    warning instead of failing the whole check."""
