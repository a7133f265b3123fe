"""The parser facade: PRISM text or file → AST nodes, lark errors → ``PrismSyntaxError``.

Text is parsed by the fast path (:mod:`veribattery.lang.fastparse`) first; whatever
it does not vouch for -- every error among it -- is parsed again by the LALR parser
built once from ``prism.lark`` (next to this module), the grammar of record, which
gives the result or the ``file:line:col`` message with a caret. lark is imported
only then.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

from veribattery._collector import collections_spaced
from veribattery._text import decode_text
from veribattery.errors import ArgumentError, PrismSyntaxError, Span, VeribatteryError
from veribattery.lang.fastparse import Fallback, parse_fast
from veribattery.lang.lexer import KEYWORDS
from veribattery.lang.nodes import Model, PropertiesFile, Property
from veribattery.lang.ops import FUNCTIONS
from veribattery.lang.transform import OTHER_MODEL_TYPES, ToNodes, unsupported_type

if TYPE_CHECKING:
    from lark import Lark, UnexpectedInput

__all__ = ["names_a_file", "parse_model", "parse_properties", "parse_property"]

_GRAMMAR = Path(__file__).with_name("prism.lark")
# Terminals that can start an operand: listed together as "an expression".
_OPERAND_STARTS = frozenset(
    {
        "IDENT",
        "INT",
        "DOUBLE",
        "STRING",
        "LPAR",
        "MINUS",
        "NOT",
        "TRUE",
        "FALSE",
        "FUNC",
        "MIN",
        "MAX",
        "FLOOR",
        "CEIL",
        "POW",
        "MOD",
        "LOG",
        "ROUND",
        "P",
        "R",
        "S",
        "FILTER",
        "NEXT",
        "FINALLY",
        "GLOBALLY",
    }
)
_REGEX_NAMES = {
    "IDENT": "a name",
    "INT": "a number",
    "DOUBLE": "a number",
    "STRING": "a quoted name",
}
_MAX_EXPECTED = 6


@functools.cache
def _lark() -> Lark:
    from lark import Lark

    return Lark(
        _GRAMMAR.read_text(encoding="utf-8"),
        parser="lalr",
        lexer="contextual",
        start=["start_model", "start_props", "start_property"],
        propagate_positions=True,
        maybe_placeholders=False,
        cache=True,
    )


#: The most a model or properties file may hold. QVBS's largest PRISM model is a few
#: hundred kB, and parsing takes some 80 bytes of memory per byte of text (10 MB: 0.8
#: GB): a larger file is not a model, or could not be parsed anyway. Only this much
#: (and one byte) is read, so /dev/zero or an endless pipe ends at once.
MAX_PRISM_FILE_BYTES = 64 << 20


def _read(source: str | Path, name: str | None, what: str) -> tuple[str, str]:
    """The text and the name used in error messages; a str is PRISM text, never a path
    (*what*: the kind of file, for the message on one that is too large)."""
    if isinstance(source, str):
        return source, name or "<string>"
    if not isinstance(source, Path):
        raise ArgumentError.wrong_kind("source", source, "a Path to read or PRISM text (a str)",
                                       "Path('model.pm'), or the text itself")
    shown = name or str(source)
    try:
        with source.open("rb") as stream:
            data = stream.read(MAX_PRISM_FILE_BYTES + 1)
    except FileNotFoundError:
        raise PrismSyntaxError(f"file not found: {source}") from None
    except OSError as exc:
        raise PrismSyntaxError(f"cannot read {source}: {exc.strerror or exc}") from None
    if len(data) > MAX_PRISM_FILE_BYTES:
        raise PrismSyntaxError(f"{shown}: more than {MAX_PRISM_FILE_BYTES >> 20} MB; {what}")
    return decode_text(data, shown, PrismSyntaxError), shown


def _describe_terminal(name: str) -> str:
    if name in _REGEX_NAMES:
        return _REGEX_NAMES[name]
    if name == "$END":
        return "end of input"
    pattern = _lark().get_terminal(name).pattern
    return f"'{pattern.value}'" if pattern.type == "str" else name


def _expected(names: set[str]) -> str:
    """A short English list of what the parser would have accepted."""
    words = [] if not names & {"IDENT", "INT", "LPAR"} else ["an expression"]
    rest = sorted(names - _OPERAND_STARTS) if words else sorted(names)
    words += [_describe_terminal(n) for n in rest]
    words = list(dict.fromkeys(words))
    if len(words) > _MAX_EXPECTED:
        words = [*words[:_MAX_EXPECTED], "..."]
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]


def _caret(text: str, line: int, col: int) -> str:
    lines = text.splitlines()
    if not 0 < line <= len(lines):
        return ""
    return f"\n  {lines[line - 1].expandtabs(1)}\n  {' ' * (col - 1)}^"


def _shown_char(char: str) -> str:
    """*char* quoted, a control character escaped (a NUL byte must not reach the terminal)."""
    return f"'{char}'" if char.isprintable() else repr(char)


def _syntax_error(exc: UnexpectedInput, text: str, source: str, *,
                  model: bool) -> PrismSyntaxError:
    from lark import UnexpectedCharacters, UnexpectedToken

    line, col = exc.line, exc.column
    if model and (declared := _declared_type(text)) is not None:  # (pomdp's observables...)
        message, (line, col) = unsupported_type(declared[0]), declared[1]
    elif isinstance(exc, UnexpectedCharacters):
        message = f"unexpected character {_shown_char(exc.char)}"
    elif isinstance(exc, UnexpectedToken) and (named := _named(exc, text)) is not None:
        message = named
    elif isinstance(exc, UnexpectedToken) and exc.token.type != "$END":
        message = f"unexpected token '{exc.token}' (expected {_expected(set(exc.expected))})"
        if (temporal := _after_temporal(exc, text)) is not None:
            message += (f"; '{temporal}' before it reads as a temporal operator nested in a "
                        f"formula: write it in parentheses, as in ({temporal} ...), as PRISM "
                        "requires of a temporal operand of &, |, => or !")
    else:
        line, col = _end_position(text)
        expected = set(exc.expected) if isinstance(exc, UnexpectedToken) else set()
        message = "unexpected end of input" + (
            f" (expected {_expected(expected)})" if expected else ""
        )
    if line < 1:
        line, col = _end_position(text)
    return PrismSyntaxError(message + _caret(text, line, col), Span(line, col, source))


def _token(exc: UnexpectedInput) -> tuple[str, int] | None:
    """*exc*'s token and its position in the text, where it has both."""
    token = getattr(exc, "token", None)
    if token is None or token.start_pos is None:
        return None
    return str(token), int(token.start_pos)


def _named(exc: UnexpectedInput, text: str) -> str | None:
    """What *exc*'s token shows the text to be, where it is something veribattery
    refuses by name (an unknown function, an unbounded int, Storm's reward bounds, a
    system block, an interval probability), else None."""
    found = _token(exc)
    if found is None:
        return None
    word, at = found
    if (callee := _unknown_call(word, at, text)) is not None:
        return (f"unknown function '{callee}' (PRISM's functions: "
                f"{', '.join(sorted(FUNCTIONS))}; and filter(...))")
    before = text[:at].rstrip()
    if word == "int" and before.endswith(":"):
        return ("an unbounded int variable is not supported (PRISM simulates them only): "
                "give it a range, name : [low..high]")
    if (storm := _storm_reward_bounds(word, text[:at])) is not None:
        return storm
    if word == "system":
        return ("a system ... endsystem block (PRISM's process-algebra composition) is not "
                "supported; without it every module runs in parallel, synchronising on "
                "shared actions (PRISM's default, the same as M1 || M2 || ...)")
    if word == "[" and before.endswith(("->", "+")):  # where an update's probability starts
        return ("an interval probability ([low,high]:update) makes an interval model "
                "(IDTMC, IMDP), which veribattery does not support")
    return None


def _unknown_call(word: str, at: int, text: str) -> str | None:
    """The name shown being called though no function has it: ``flor(`` at the ``(``
    (the token *word* at *at*), or ``fiter(forall, ...)`` at a token inside the
    parentheses."""
    opening = at if word == "(" else _unclosed_paren(text, at)
    if opening is None:
        return None
    name = re.search(r"([A-Za-z_]\w*)[ \t]*$", text[:opening])
    # A keyword before "(" is no call to report (F (a), init (...), a function's name).
    return None if name is None or name.group(1) in KEYWORDS else name.group(1)


def _unclosed_paren(text: str, end: int) -> int | None:
    """The position of the innermost ``(`` still open at *end*, if any."""
    depth = 0
    for position in range(end - 1, -1, -1):
        char = text[position]
        if char == ")":
            depth += 1
        elif char == "(":
            if depth == 0:
                return position
            depth -= 1
        elif char in ";\n" and depth == 0:
            return None
    return None


def _after_temporal(exc: UnexpectedInput, text: str) -> str | None:
    """The temporal operator (``X``, ``F``, ``G``) written just before *exc*'s token, as
    in ``F a & X "done"``, where the parser took it for a name."""
    found = _token(exc)
    if found is None:
        return None
    before = re.search(r"(?:^|[\s(&|!])([XFG])\s*$", text[:found[1]])
    return None if before is None else before.group(1)


#: Storm's reward-bound extensions PRISM's language does not have.
_SEVERAL_BOUNDS = re.compile(r'[FU]\s*\{\s*"[^"]*"\s*\}\s*(?:<=|<|>=|>)[^,\[\]]*$')
_BOUNDED_C = re.compile(r'\bC\s*\{\s*"[^"]*"\s*\}\s*$')


def _storm_reward_bounds(word: str, before: str) -> str | None:
    """What Storm-only reward bound the token *word* (after the text *before*) stopped
    at, if any: several bounds on one ``F`` (``F{"a"}<=3,{"b"}>1``) or a reward-bounded
    ``C`` (``C{"r"}<=3``)."""
    if word == "," and _SEVERAL_BOUNDS.search(before):
        return ("several reward bounds on one F or U (Storm's multi-dimensional bounds) are "
                "not supported: one bound, F{\"r\"}<=k, is")
    if word in ("<=", "<", ">=", ">") and _BOUNDED_C.search(before):
        return ("a reward-bounded C (Storm's C{\"r\"}<=k) is not supported: C<=k bounds "
                "the steps, and R{\"r\"}=? [ C<=k ] their reward")
    return None


def _declared_type(text: str) -> tuple[str, tuple[int, int]] | None:
    """A model type that veribattery refuses, when it is the file's first word (after
    comments), with its line and column."""
    found = re.match(r"(?:\s+|//[^\n]*)*([A-Za-z_]\w*)", text)
    if found is None or found.group(1) not in OTHER_MODEL_TYPES:
        return None
    start = found.start(1)
    line = text.count("\n", 0, start) + 1
    return found.group(1), (line, start - (text.rfind("\n", 0, start) + 1) + 1)


def _end_position(text: str) -> tuple[int, int]:
    lines = text.splitlines() or [""]
    return len(lines), len(lines[-1]) + 1


@functools.cache
def _transformer() -> Any:
    """:class:`ToNodes` as a lark transformer: each rule method called with its meta.

    The non-recursive transformer: a left-deep chain ``a | b | c ...`` of thousands
    of terms is a parse tree as deep, beyond Python's recursion limit.
    """
    from lark import Transformer_NonRecursive, v_args

    rules = {
        name: v_args(meta=True)(getattr(ToNodes, name))
        for name in dir(ToNodes)
        if not name.startswith("_") and callable(getattr(ToNodes, name))
    }
    return type("LarkToNodes", (ToNodes, Transformer_NonRecursive), rules)


def _parse(text: str, source: str, start: str) -> Any:
    try:
        return parse_fast(text, source, start)
    except Fallback:
        return _parse_with_lark(text, source, start)


def _parse_with_lark(text: str, source: str, start: str) -> Any:
    """Parse with lark (the grammar of record): the result, or the error message."""
    from lark import UnexpectedInput
    from lark.exceptions import VisitError

    try:
        tree = _lark().parse(text, start=start)
        return _transformer()(text, source).transform(tree)
    except UnexpectedInput as exc:
        raise _syntax_error(exc, text, source, model=start == "start_model") from None
    except VisitError as exc:
        if isinstance(exc.orig_exc, VeribatteryError):
            raise exc.orig_exc from None
        raise


@collections_spaced
def parse_model(source: str | Path, *, name: str | None = None) -> Model:
    """Parse a PRISM model: a :class:`~pathlib.Path` to read, or a str of PRISM text.

    :param source: the file, or the model text itself (a str is never taken as a path)
    :param name: the name used in error messages (default: the path, or ``<string>``)
    :raises PrismSyntaxError: if the file is missing or the text does not parse
    :raises PrismSemanticError: if the model is neither a DTMC nor an MDP
    :raises ArgumentError: for *source* neither a Path nor a str
    """
    model: Model = _parse_source(source, name, "start_model")
    return model


def parse_properties(source: str | Path, *, name: str | None = None) -> PropertiesFile:
    """Parse a PRISM properties file (``.props``/``.pctl``); ``;`` between items is optional.

    :param source: the file, or the properties text itself
    :param name: the name used in error messages
    :raises PrismSyntaxError: if the file is missing or the text does not parse
    :raises ArgumentError: for *source* neither a Path nor a str
    """
    props: PropertiesFile = _parse_source(source, name, "start_props")
    return props


#: The suffixes of PRISM's model and properties files, for telling a file's name apart.
_PRISM_SUFFIXES = (".pm", ".nm", ".prism", ".props", ".pctl", ".prop")


#: What a file of each kind holds, said when one is larger than any of them.
_TOO_LARGE = {"start_model": "a PRISM model is at most a few MB (one written state by state, "
                              "as --export-induced writes, passes 64 MB past ~550,000 states)",
              "start_props": "a properties file is at most a few kB"}


def _parse_source(source: str | Path, name: str | None, start: str) -> Any:
    """Parse *source*; a str that does not parse and names a file says to give a Path
    (a notebook's ``parse_model("die.pm")`` is otherwise an "unexpected token")."""
    text, label = _read(source, name, _TOO_LARGE[start])
    try:
        return _parse(text, label, start)
    except PrismSyntaxError:
        if not (isinstance(source, str) and names_a_file(source)):
            raise
    raise PrismSyntaxError(f"{source!r} was parsed as PRISM text, since a str is the text "
                           f"itself: give Path({source!r}) to read the file") from None


def names_a_file(text: str) -> bool:
    """Whether *text*, given where a model or properties are expected, reads as a file's
    name (one line, a PRISM suffix or an existing file) rather than PRISM text."""
    one_line = text.strip() and "\n" not in text.strip() and len(text) < 4096
    return bool(one_line) and (text.strip().endswith(_PRISM_SUFFIXES)
                               or Path(text.strip()).is_file())


def parse_property(text: str) -> Property:
    """Parse one property, e.g. ``P=? [ F "done" ]`` or ``"name": R=? [ C<=10 ]``.

    :raises PrismSyntaxError: if the text is not a single property
    :raises ArgumentError: for anything but a str (a file: :func:`parse_properties`)
    """
    if not isinstance(text, str):
        raise ArgumentError.wrong_kind(
            "text", text, "one property's text", "e.g. 'P=? [ F \"done\" ]'; a file's "
            "properties are veribattery.parse_properties(Path('model.props')).properties")
    prop: Property = _parse(text, "<property>", "start_property")
    return prop
