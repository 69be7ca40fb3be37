"""Action values: the YAML flow mapping of a message or service request (``{data: 3}``).

An ``<action>``'s ``<value>`` is what ``rostopic pub`` would take: a YAML flow mapping such as
``{linear: {x: 0.5, y: 0}, angular: {z: -0.2}}``. ruamel.yaml's parser reads it (its events
only: nothing is constructed, as in :mod:`imrosc.graph.yamltree`), and this module builds the
value, refusing what an action value never needs:

* the text is one mapping ``{...}``, with whitespace (line breaks included) around it;
* keys are plain or quoted scalars and stay strings; duplicate keys are errors;
* values are mappings, sequences ``[...]``, quoted strings or plain scalars; a single trailing
  comma is allowed in a collection, as in YAML; quoted strings stay on one line;
* plain scalars are resolved by the YAML 1.2 core schema (null, booleans, decimal, ``0o`` and
  ``0x`` integers, floats with ``.inf`` and ``.nan``; anything else is a string).

Refused with :class:`FlowMapError`: anchors (``&``), aliases (``*``), tags (``!``), comments,
complex keys (``?``), keys without a value, values left empty, a lone ``-``, a ``:`` that
would start a nested mapping without braces (``{a: b: c}``, ``[b: c]``), text before or after
the mapping, and collections nested more than :data:`MAX_NESTING` deep. So are what YAML
refuses or ruamel.yaml reads otherwise, each with a way around it: a character YAML does not
allow in a stream or reads as a line break (U+0085, U+2028, U+2029: an escape in a
double-quoted string), a tab inside a plain scalar (quote the value), a key on several lines
or whose ``:`` is on a later line (one line), and a plain key whose ``:`` touches a ``[`` or
``{`` (a space after the ``:``).
"""

from __future__ import annotations

import re

from ruamel.yaml import YAML
from ruamel.yaml.error import MarkedYAMLError, YAMLError
from ruamel.yaml.events import (
    AliasEvent,
    CollectionEndEvent,
    CollectionStartEvent,
    Event,
    MappingStartEvent,
    NodeEvent,
    ScalarEvent,
)
from ruamel.yaml.reader import Reader, ReaderError

from imrosc.schema.positions import OffsetError

__all__ = ["MAX_NESTING", "FlowMapError", "parse_flow_mapping"]

MAX_NESTING = 64
"""The deepest nesting of mappings and sequences a value may have."""

_SPACES = " \t\r\n"
_NULL = frozenset({"null", "Null", "NULL", "~"})
_TRUE = frozenset({"true", "True", "TRUE"})
_FALSE = frozenset({"false", "False", "FALSE"})
_DECIMAL = re.compile(r"[-+]?[0-9]+")
_OCTAL = re.compile(r"0o[0-7]+")
_HEXADECIMAL = re.compile(r"0x[0-9a-fA-F]+")
_FLOAT = re.compile(r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?")
_INFINITY = re.compile(r"[-+]?\.(?:inf|Inf|INF)")
_NAN = frozenset({".nan", ".NaN", ".NAN"})
_MAX_INT_DIGITS = 4000
_UNREADABLE = re.compile("[\x85\u2028\u2029]|" + Reader.NON_PRINTABLE.pattern)
"""Characters YAML does not allow in a stream, and its line breaks other than CR and LF."""
_LONG_ESCAPE = re.compile(r"\\U(?:0*1[1-9a-fA-F]|0*[2-9a-fA-F][0-9a-fA-F])[0-9a-fA-F]{4}")
"""A double-quoted string's escape of a code point above U+10FFFF."""
_ENDS_PLAIN = ("", *_SPACES, *",[]{}")
"""What may follow a plain scalar's ':' or lone '-' for them to be indicators."""
_NESTED = "unexpected ':'; a nested mapping needs braces, e.g. {a: {b: 1}}"
_TAB = "a tab inside a plain value is not supported; quote the value"
_COMMENT = "comments are not supported in an action value"
_BETWEEN = {"#": _COMMENT, "?": "complex keys ('?') are not supported"}
"""What may stand between two nodes besides spaces, ',' and ':', and why it is refused."""


class FlowMapError(OffsetError):
    """An action value that is not a supported flow mapping: a message and a 0-based offset."""


def _show(text: str) -> str:
    if len(text) > 40:
        text = text[:37] + "..."
    return repr(text)


def _start(event: Event) -> int:
    return int(event.start_mark.index)


def _end(event: Event) -> int:
    return int(event.end_mark.index)


class _Builder:
    """One pass over the parser's events: the open collections and the finished value."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.stack: list[tuple[dict[str, object] | list[object], int]] = []
        self.keys: list[tuple[str, int, int, bool] | None] = []
        """Per open collection: a mapping's key waiting for its value (text, start, end,
        whether it is plain)."""
        self.last = 0
        """Where the previous event ended: what lies between it and the next is checked."""
        self.result: dict[str, object] | None = None

    def between(self, until: int) -> None:
        """Refuse a comment or a complex key between the previous event and ``until``, or a
        tab that ended a plain scalar there."""
        self.tab(until)
        gap = self.text[self.last : until]
        for index, char in enumerate(gap):
            if char in _BETWEEN:
                raise FlowMapError(_BETWEEN[char], self.last + index)

    def tab(self, until: int, *, error: bool = False) -> None:
        """Refuse a tab right after a plain scalar's text when more text than commas, colons
        and closing brackets follows it before ``until`` (or the parser failed there):
        ruamel.yaml ends a plain scalar at a tab, which YAML does not."""
        tab = self.text.find("\t", self.last, until)
        if tab <= 0 or self.text[tab - 1] in _SPACES + ",[{:":
            return
        if error or self.text[tab:until].strip(_SPACES + ",:]}"):
            raise FlowMapError(_TAB, tab)

    def feed(self, event: Event) -> bool:
        """Take one event; True once the outer mapping is complete."""
        if not isinstance(event, NodeEvent) and not isinstance(event, CollectionEndEvent):
            return False
        start = _start(event)
        self.between(start)
        self.screen(event)
        if isinstance(event, ScalarEvent):
            self.scalar(event)
        elif isinstance(event, CollectionStartEvent):
            self.open(event)
        elif isinstance(event, CollectionEndEvent):
            closed, _ = self.stack.pop()
            self.keys.pop()
            self.last = _end(event)
            if not self.stack:
                assert isinstance(closed, dict)
                self.result = closed
                return True
            self.add(closed, start, self.last)
        return False

    def screen(self, event: Event) -> None:
        start = _start(event)
        if isinstance(event, AliasEvent):
            raise FlowMapError("aliases ('*') are not supported", start)
        if isinstance(event, NodeEvent) and event.anchor is not None:
            raise FlowMapError("anchors ('&') are not supported", start)
        if isinstance(event, (ScalarEvent, CollectionStartEvent)) and event.tag is not None:
            raise FlowMapError("tags ('!') are not supported", start)

    def open(self, event: CollectionStartEvent) -> None:
        start = _start(event)
        if self.stack and self.text[start : start + 1] not in ("{", "["):
            raise FlowMapError(_NESTED, self.text.index(":", start))
        if self.stack and isinstance(self.stack[-1][0], dict) and self.keys[-1] is None:
            raise FlowMapError("keys must be plain or quoted names, not collections", start)
        if len(self.stack) >= MAX_NESTING:
            raise FlowMapError(f"collections are nested deeper than {MAX_NESTING} levels", start)
        opened: dict[str, object] | list[object] = (
            {} if isinstance(event, MappingStartEvent) else []
        )
        self.stack.append((opened, start))
        self.keys.append(None)
        self.last = _end(event)

    def scalar(self, event: ScalarEvent) -> None:
        start, end = _start(event), _end(event)
        value = str(event.value)
        if event.style is None:
            if not value:
                self.empty()
            after = self.text[end : end + 1]
            if value == "-" and after in _ENDS_PLAIN:
                message = "a lone '-' is not a value; quote it, or write a sequence as [a, b]"
                raise FlowMapError(message, start)
            if value.endswith(":") and after in _ENDS_PLAIN:
                if after in ("[", "{") and self.keys[-1] is None:
                    message = f"expected ': ' after a key; put a space after ':' in {_show(value)}"
                    raise FlowMapError(message, end - 1)
                raise FlowMapError(_NESTED, start + self.text[start:end].rindex(":"))
        elif any(char in "\r\n" for char in self.text[start:end]):
            raise FlowMapError("quoted strings must end on the line they start", start)
        self.last = end
        parent = self.stack[-1][0]
        if isinstance(parent, dict) and self.keys[-1] is None:
            if value in parent:
                raise FlowMapError(f"duplicate key {_show(value)}", start)
            self.keys[-1] = (value, start, end, event.style is None)
            return
        self.add(value if event.style is not None else _resolve(value, start), start, end)

    def empty(self) -> None:
        """Refuse a missing key or value (the parser's empty scalar after :attr:`last`)."""
        parent = self.stack[-1][0]
        key = self.keys[-1]
        here = self.skip(self.last)
        if not isinstance(parent, dict):
            raise FlowMapError("empty entry in a sequence", here)
        if key is None:
            raise FlowMapError("missing key before ':'", here)
        name, start, end, _ = key
        if self.text.startswith(":", here) and any(c in "\r\n" for c in self.text[start:here]):
            message = f"key {_show(name)} and its ':' must be on one line"
            raise FlowMapError(message, here)
        if self.text.startswith(":", here):
            raise FlowMapError(f"key {_show(name)} has no value", self.skip(here + 1))
        after = self.skip(end)
        if "\t" in self.text[end:after] and self.text[after : after + 1] not in ("", ",", "}"):
            raise FlowMapError(_TAB, self.text.index("\t", end))
        if ":" in name:
            message = f"expected ': ' after a key; put a space after ':' in {_show(name)}"
            raise FlowMapError(message, start + self.text[start:end].index(":"))
        raise FlowMapError(f"expected ':' after key {_show(name)}", here)

    def skip(self, offset: int) -> int:
        """The first offset from ``offset`` on that is not a space."""
        return len(self.text) - len(self.text[offset:].lstrip(_SPACES))

    def add(self, value: object, start: int, end: int) -> None:
        """Put a finished value into the open collection."""
        parent = self.stack[-1][0]
        if isinstance(parent, list):
            parent.append(value)
            return
        key = self.keys[-1]
        if key is None:
            raise FlowMapError("keys must be plain or quoted names, not collections", start)
        name, _, end, plain = key
        colon = self.text.index(":", end)
        if plain and self.text[colon + 1 : colon + 2] not in _ENDS_PLAIN:
            raise FlowMapError(f"expected ': ' after key {_show(name)}", colon)
        parent[name] = value
        self.keys[-1] = None

    def syntax(self, error: Exception) -> FlowMapError:
        """A parser error as a :class:`FlowMapError` at its place."""
        offset, message = len(self.text), str(error).split("\n")[0]
        if isinstance(error, MarkedYAMLError):
            mark = error.problem_mark or error.context_mark
            offset = int(mark.index) if mark is not None else offset
            message = str(error.problem or error.context or message)
            context = error.context_mark
            scanned = None if context is None or context.index < self.last else context.index
            self.tab(offset, error=True)
            self.between(offset if scanned is None else int(scanned))
            if "<stream end>" in message and self.stack:
                opening = self.stack[-1][1]
                return FlowMapError(f"unbalanced {self.text[opening]!r}", opening)
            if "end of stream" in message and scanned is not None:
                quote = self.text[scanned]
                return FlowMapError(f"unterminated string starting with {quote}", scanned)
            if message.endswith("got ':'"):
                return FlowMapError(_NESTED, offset)
            if message.endswith("found ','") and self.stack:
                what = "mapping" if isinstance(self.stack[-1][0], dict) else "sequence"
                return FlowMapError(f"empty entry in a {what}", offset)
        elif isinstance(error, ReaderError) and isinstance(error.position, int):
            offset = error.position
        elif isinstance(error, ValueError):
            found = _LONG_ESCAPE.search(self.text, self.last)
            offset = found.start() if found else self.last
            return FlowMapError("a '\\U' escape that is not a unicode character", offset)
        return FlowMapError(f"invalid YAML: {message}", min(offset, len(self.text)))


def _resolve(raw: str, start: int) -> object:
    """Resolve a plain scalar by the YAML 1.2 core schema."""
    if raw in _NULL:
        return None
    if raw in _TRUE:
        return True
    if raw in _FALSE:
        return False
    if _DECIMAL.fullmatch(raw):
        return _big_int(raw, 10, start)
    if _OCTAL.fullmatch(raw):
        return _big_int(raw[2:], 8, start)
    if _HEXADECIMAL.fullmatch(raw):
        return _big_int(raw[2:], 16, start)
    if _FLOAT.fullmatch(raw):
        return float(raw)
    if _INFINITY.fullmatch(raw):
        return float("-inf") if raw.startswith("-") else float("inf")
    if raw in _NAN:
        return float("nan")
    return raw


def _big_int(digits: str, base: int, start: int) -> int:
    if len(digits) > _MAX_INT_DIGITS:
        raise FlowMapError("integer is too long", start)
    return int(digits, base)


def parse_flow_mapping(text: str) -> dict[str, object]:
    """Parse an action value; raise :class:`FlowMapError` with an offset into ``text``.

    Returns plain Python data: nested ``dict[str, object]``, ``list``, ``str``, ``int``,
    ``float``, ``bool`` and ``None``.
    """
    first = len(text) - len(text.lstrip(_SPACES))
    if first == len(text):
        raise FlowMapError("the value is empty; expected a mapping such as {data: 3}", 0)
    if text[first] != "{":
        raise FlowMapError("the value must be a mapping in braces, such as {data: 3}", first)
    unreadable = _UNREADABLE.search(text)
    if unreadable:
        code = f"{ord(unreadable.group()):04X}"
        message = f'character U+{code} is not allowed; write it as the escape "\\u{code}"'
        raise FlowMapError(message, unreadable.start())
    # the spaces around the mapping as plain spaces: YAML refuses a tab where a token could
    # start outside a collection, as in a value's indentation in the XML
    source = " " * first + text[first:].rstrip(_SPACES)
    builder = _Builder(source)
    try:
        for event in YAML(typ="safe", pure=True).parse(source):
            if builder.feed(event):
                break
    except FlowMapError:
        raise
    except (YAMLError, ValueError) as error:
        raise builder.syntax(error) from None
    rest = len(text) - len(text[builder.last :].lstrip(_SPACES))
    if builder.result is None or rest < len(text):
        shown = repr(text[rest]) if rest < len(text) else "the end of the value"
        raise FlowMapError(f"unexpected {shown} after the closing '}}'", rest)
    return builder.result
