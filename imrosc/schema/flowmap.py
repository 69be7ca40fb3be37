"""Action values: the YAML flow mapping of a message or service request (``{data: 3}``).

An ``<action>``'s ``<value>`` is what ``rostopic pub`` would take: a YAML flow mapping such as
``{linear: {x: 0.5, y: 0}, angular: {z: -0.2}}``. This module parses the subset of YAML that
such values need with a small recursive-descent parser, without a YAML library:

* the text is one mapping ``{...}``, with whitespace (line breaks included) around tokens;
* keys are plain or quoted scalars and stay strings; duplicate keys are errors;
* values are mappings, sequences ``[...]``, quoted strings or plain scalars; a single trailing
  comma is allowed in a collection, as in YAML;
* single-quoted strings escape ``'`` as ``''``; double-quoted strings take YAML's backslash
  escapes (``\\\\ \\" \\/ \\0 \\a \\b \\t \\n \\v \\f \\r \\e \\N \\_ \\L \\P``, a space,
  ``\\xXX``, ``\\uXXXX``, ``\\UXXXXXXXX``); quoted strings stay on one line;
* plain scalars end at ``,``, ``]``, ``}``, at ``: `` and at `` #``, are stripped, fold line
  breaks as YAML does, and are resolved by the YAML 1.2 core schema (null, booleans, decimal,
  ``0o`` and ``0x`` integers, floats with ``.inf`` and ``.nan``; anything else is a string).

Everything YAML offers beyond that is refused with :class:`FlowMapError`: anchors (``&``),
aliases (``*``), tags (``!``), comments, block scalars, complex keys (``?``), keys without a
value and values left empty. Collections nest at most :data:`MAX_NESTING` deep.
"""

from __future__ import annotations

import re

__all__ = ["MAX_NESTING", "FlowMapError", "parse_flow_mapping"]

MAX_NESTING = 64
"""The deepest nesting of mappings and sequences a value may have."""

_SPACES = " \t\r\n"
_FLOW_INDICATORS = ",[]{}"
_LINE_BREAK = re.compile(r"\r\n|\r|\n")
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
_ESCAPES = {
    "\\": "\\",
    '"': '"',
    "/": "/",
    " ": " ",
    "\t": "\t",
    "0": "\0",
    "a": "\a",
    "b": "\b",
    "t": "\t",
    "n": "\n",
    "v": "\v",
    "f": "\f",
    "r": "\r",
    "e": "\x1b",
    "N": "\x85",
    "_": "\xa0",
    "L": "\u2028",
    "P": "\u2029",
}
_HEX_ESCAPES = {"x": 2, "u": 4, "U": 8}
_HEX_DIGITS = frozenset("0123456789abcdefABCDEF")
_REFUSED_STARTS = {
    "&": "anchors ('&') are not supported",
    "*": "aliases ('*') are not supported",
    "!": "tags ('!') are not supported",
    "#": "comments are not supported in an action value",
    "|": "block scalars ('|') are not supported in a flow mapping",
    ">": "block scalars ('>') are not supported in a flow mapping",
    "?": "complex keys ('?') are not supported",
    "%": "'%' cannot start a plain value; quote it",
    "@": "'@' cannot start a plain value; quote it",
    "`": "'`' cannot start a plain value; quote it",
}


class FlowMapError(ValueError):
    """An action value that is not a supported flow mapping: a message and a 0-based offset."""

    def __init__(self, message: str, offset: int) -> None:
        super().__init__(message, offset)
        self.message = message
        self.offset = offset

    def __str__(self) -> str:
        return f"{self.message} (at offset {self.offset})"


def _show(text: str) -> str:
    if len(text) > 40:
        text = text[:37] + "..."
    return repr(text)


class _Parser:
    def __init__(self, text: str) -> None:
        self.text = text
        self.position = 0
        self.depth = 0

    # -- helpers ------------------------------------------------------------------------------

    def char(self) -> str:
        """The current character, or '' at the end."""
        return self.text[self.position] if self.position < len(self.text) else ""

    def skip_spaces(self) -> None:
        while self.position < len(self.text) and self.text[self.position] in _SPACES:
            self.position += 1

    def fail(self, message: str, offset: int | None = None) -> FlowMapError:
        return FlowMapError(message, self.position if offset is None else offset)

    def describe_here(self) -> str:
        char = self.char()
        return "the end of the value" if not char else repr(char)

    # -- grammar ------------------------------------------------------------------------------

    def parse(self) -> dict[str, object]:
        self.skip_spaces()
        if not self.char():
            raise self.fail("the value is empty; expected a mapping such as {data: 3}", 0)
        if self.char() != "{":
            raise self.fail("the value must be a mapping in braces, such as {data: 3}")
        result = self.mapping()
        self.skip_spaces()
        if self.char():
            raise self.fail(f"unexpected {self.describe_here()} after the closing '}}'")
        return result

    def enter(self) -> None:
        if self.depth >= MAX_NESTING:
            raise self.fail(f"collections are nested deeper than {MAX_NESTING} levels")
        self.depth += 1

    def mapping(self) -> dict[str, object]:
        opening = self.position
        self.enter()
        self.position += 1  # '{'
        result: dict[str, object] = {}
        while True:
            self.skip_spaces()
            char = self.char()
            if char == "}":
                self.position += 1
                self.depth -= 1
                return result
            if not char:
                raise self.fail("unbalanced '{'", opening)
            key_offset = self.position
            key = self.key()
            if key in result:
                raise self.fail(f"duplicate key {_show(key)}", key_offset)
            self.skip_spaces()
            if self.char() != ":":
                if ":" in key:
                    message = f"expected ': ' after a key; put a space after ':' in {_show(key)}"
                    raise self.fail(message, key_offset + key.index(":"))
                raise self.fail(f"expected ':' after key {_show(key)}")
            self.position += 1
            self.skip_spaces()
            if self.char() in ("", ",", "}"):
                raise self.fail(f"key {_show(key)} has no value")
            result[key] = self.value()
            self.separator("}", opening, "mapping")

    def sequence(self) -> list[object]:
        opening = self.position
        self.enter()
        self.position += 1  # '['
        result: list[object] = []
        while True:
            self.skip_spaces()
            char = self.char()
            if char == "]":
                self.position += 1
                self.depth -= 1
                return result
            if not char:
                raise self.fail("unbalanced '['", opening)
            if char == ",":
                raise self.fail("empty entry in a sequence")
            result.append(self.value())
            self.separator("]", opening, "sequence")

    def separator(self, closing: str, opening: int, what: str) -> None:
        """After an entry: accept ',' or leave the closing bracket for the caller."""
        self.skip_spaces()
        char = self.char()
        if char == ",":
            self.position += 1
            self.skip_spaces()
            if self.char() == ",":
                raise self.fail(f"empty entry in a {what}")
            return
        if char == closing:
            return
        if not char:
            raise self.fail(f"unbalanced '{self.text[opening]}'", opening)
        if char == ":":
            raise self.fail("unexpected ':'; a nested mapping needs braces, e.g. {a: {b: 1}}")
        if char in "]}":
            raise self.fail(f"{char!r} does not close the {self.text[opening]!r} opened before")
        raise self.fail(f"expected ',' or {closing!r} but found {self.describe_here()}")

    def key(self) -> str:
        char = self.char()
        if char in ("'", '"'):
            return self.quoted()
        if char in ("{", "["):
            raise self.fail("keys must be plain or quoted names, not collections")
        if char == ":":
            raise self.fail("missing key before ':'")
        start = self.position
        raw = self.plain()
        if not raw:
            raise self.fail(f"expected a key but found {self.describe_here()}", start)
        return raw

    def value(self) -> object:
        char = self.char()
        if char == "{":
            return self.mapping()
        if char == "[":
            return self.sequence()
        if char in ("'", '"'):
            return self.quoted()
        start = self.position
        raw = self.plain()
        if not raw:
            raise self.fail(f"expected a value but found {self.describe_here()}", start)
        return self.resolve(raw, start)

    def plain(self) -> str:
        """Read a plain scalar; return it stripped and folded ('' if there is none)."""
        start = self.position
        char = self.char()
        if char in _REFUSED_STARTS:
            raise self.fail(_REFUSED_STARTS[char])
        if char == "-" and self.following_is_space(self.position + 1, flow=True):
            raise self.fail("a lone '-' is not a value; quote it, or write a sequence as [a, b]")
        text = self.text
        while self.position < len(text):
            char = text[self.position]
            if char in _FLOW_INDICATORS:
                break
            if char == ":" and self.following_is_space(self.position + 1, flow=True):
                break
            if char == "#" and self.position > start and text[self.position - 1] in _SPACES:
                raise self.fail("comments are not supported in an action value")
            self.position += 1
        return _fold(text[start : self.position])

    def following_is_space(self, index: int, *, flow: bool = False) -> bool:
        if index >= len(self.text):
            return True
        char = self.text[index]
        return char in _SPACES or (flow and char in _FLOW_INDICATORS)

    def quoted(self) -> str:
        quote = self.char()
        opening = self.position
        self.position += 1
        pieces: list[str] = []
        text = self.text
        while self.position < len(text):
            char = text[self.position]
            if char in "\r\n":
                raise self.fail("quoted strings must end on the line they start", opening)
            if char == quote:
                if quote == "'" and text.startswith("''", self.position):
                    pieces.append("'")
                    self.position += 2
                    continue
                self.position += 1
                return "".join(pieces)
            if char == "\\" and quote == '"':
                pieces.append(self.escape(opening))
                continue
            pieces.append(char)
            self.position += 1
        raise self.fail(f"unterminated string starting with {quote}", opening)

    def escape(self, opening: int) -> str:
        """Decode the escape at the current position of the string that starts at ``opening``."""
        start = self.position
        code = self.text[start + 1 : start + 2]
        if code in _ESCAPES:
            self.position += 2
            return _ESCAPES[code]
        if code in _HEX_ESCAPES:
            width = _HEX_ESCAPES[code]
            digits = self.text[start + 2 : start + 2 + width]
            if len(digits) != width or not all(digit in _HEX_DIGITS for digit in digits):
                raise self.fail(f"'\\{code}' needs {width} hexadecimal digits", start)
            point = int(digits, 16)
            if point > 0x10FFFF:
                raise self.fail(f"'\\{code}{digits}' is not a unicode character", start)
            self.position += 2 + width
            return chr(point)
        if not code:
            raise self.fail('unterminated string starting with "', opening)
        if code in "\r\n":
            raise self.fail("quoted strings must end on the line they start", start)
        shown = f"'\\{code}'" if code.isprintable() else repr("\\" + code)
        raise self.fail(f"unknown escape {shown} in a double-quoted string", start)

    def resolve(self, raw: str, start: int) -> object:
        """Resolve a plain scalar by the YAML 1.2 core schema."""
        if raw in _NULL:
            return None
        if raw in _TRUE:
            return True
        if raw in _FALSE:
            return False
        if _DECIMAL.fullmatch(raw):
            if len(raw) > _MAX_INT_DIGITS:
                raise self.fail("integer is too long", start)
            return int(raw)
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


def _fold(raw: str) -> str:
    """Strip a plain scalar and fold its line breaks as YAML does."""
    lines = [line.strip(" \t") for line in _LINE_BREAK.split(raw.strip(_SPACES))]
    result = lines[0]
    empty = 0
    for line in lines[1:]:
        if not line:
            empty += 1
            continue
        result += ("\n" * empty if empty else " ") + line
        empty = 0
    return result


def parse_flow_mapping(text: str) -> dict[str, object]:
    """Parse an action value; raise :class:`FlowMapError` with an offset into ``text``.

    Returns plain Python data: nested ``dict[str, object]``, ``list``, ``str``, ``int``,
    ``float``, ``bool`` and ``None``.
    """
    return _Parser(text).parse()
