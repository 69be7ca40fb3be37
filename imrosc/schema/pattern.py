"""Temporal patterns: the regular expressions of a ``<pattern>`` (thesis section 3.4.4.2).

A pattern is a regular expression over single letters::

    union   := concat ('|' concat)*
    concat  := postfix postfix*
    postfix := atom ('*' | '+')*
    atom    := LETTER | '-' | '(' union ')'

Juxtaposition concatenates, ``|`` is union, postfix ``*`` and ``+`` repeat, ``-`` is the empty
word (epsilon), and whitespace is ignored. Uppercase letters are placeholders that inference
binds to distinct events; lowercase letters name events of the scope directly. Precedence is
postfix over concatenation over union: ``ab*|c`` is ``(a(b*))|c``.

The parser returns a canonical tree: a concatenation never directly holds a concatenation and a
union never directly holds a union (both are associative, so ``(ab)c`` is ``abc``), a group is
never kept as a node, and stacked postfix operators are collapsed (``a**`` and ``a+*`` are
``a*``, ``a++`` is ``a+``), which keeps trees shallow. :func:`to_text` prints a canonical tree
with the fewest parentheses, and parsing that text gives the same tree back.
"""

from __future__ import annotations

import string
from dataclasses import dataclass

from imrosc.schema.positions import OffsetError

__all__ = [
    "MAX_NESTING",
    "Concat",
    "Epsilon",
    "Pattern",
    "PatternError",
    "Plus",
    "Star",
    "Symbol",
    "Union",
    "event_letters",
    "parse_pattern",
    "placeholders",
    "substitute",
    "to_text",
]

MAX_NESTING = 64
"""The deepest nesting of parentheses a pattern may have."""

_LETTERS = frozenset(string.ascii_letters)
_SPACES = frozenset(" \t\r\n\f\v")
_STARTS = _LETTERS | {"-", "("}


class PatternError(OffsetError):
    """A pattern that cannot be parsed: a message and the 0-based offset of the problem."""


@dataclass(frozen=True)
class Symbol:
    """One letter: an event (lowercase) or a placeholder (uppercase)."""

    letter: str


@dataclass(frozen=True)
class Epsilon:
    """The empty word, written ``-``."""


@dataclass(frozen=True)
class Concat:
    """A sequence of two or more patterns, one after the other."""

    parts: tuple[Pattern, ...]


@dataclass(frozen=True)
class Union:
    """A choice between two or more patterns."""

    options: tuple[Pattern, ...]


@dataclass(frozen=True)
class Star:
    """Zero or more repetitions."""

    inner: Pattern


@dataclass(frozen=True)
class Plus:
    """One or more repetitions."""

    inner: Pattern


Pattern = Symbol | Epsilon | Concat | Union | Star | Plus


class _Parser:
    """Recursive descent over the non-space characters of the text."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.tokens: list[tuple[str, int]] = []
        for offset, char in enumerate(text):
            if char in _SPACES:
                continue
            if char not in _LETTERS and char not in "|*+()-":
                raise PatternError(
                    f"unexpected character {char!r}; a pattern holds letters, "
                    f"'|', '*', '+', '-' and parentheses",
                    offset,
                )
            self.tokens.append((char, offset))
        self.index = 0
        self.depth = 0

    def peek(self) -> tuple[str, int]:
        if self.index < len(self.tokens):
            return self.tokens[self.index]
        return ("", len(self.text))

    def previous(self) -> tuple[str, int] | None:
        return self.tokens[self.index - 1] if self.index > 0 else None

    def parse(self) -> Pattern:
        if not self.tokens:
            raise PatternError("pattern is empty", 0)
        result = self.union()
        char, offset = self.peek()
        if char == ")":
            raise PatternError("unbalanced ')'", offset)
        if char:  # pragma: no cover - union() consumes everything else
            raise PatternError(f"unexpected {char!r}", offset)
        return result

    def union(self) -> Pattern:
        options: list[Pattern] = []
        while True:
            option = self.concat()
            options.extend(option.options if isinstance(option, Union) else (option,))
            char, _ = self.peek()
            if char != "|":
                break
            self.index += 1
        return options[0] if len(options) == 1 else Union(tuple(options))

    def concat(self) -> Pattern:
        parts: list[Pattern] = []
        while self.peek()[0] in _STARTS:
            part = self.postfix()
            parts.extend(part.parts if isinstance(part, Concat) else (part,))
        if not parts:
            self.nothing_here()
        return parts[0] if len(parts) == 1 else Concat(tuple(parts))

    def nothing_here(self) -> None:
        """Explain why a pattern was expected here and none was found."""
        char, offset = self.peek()
        before = self.previous()
        if char in ("*", "+"):
            raise PatternError(f"'{char}' has nothing before it to repeat", offset)
        if before is not None and before[0] == "|":
            if char == "|":
                raise PatternError("'|' has nothing before it", offset)
            raise PatternError("'|' has nothing after it", before[1])
        if char == "|":
            raise PatternError("'|' has nothing before it", offset)
        if before is not None and before[0] == "(":
            if char == ")":
                raise PatternError("empty group '()'", before[1])
            raise PatternError("unbalanced '('", before[1])
        if char == ")":
            raise PatternError("unbalanced ')'", offset)
        raise PatternError("pattern is empty", offset)  # pragma: no cover - caught in parse()

    def postfix(self) -> Pattern:
        result = self.atom()
        while self.peek()[0] in ("*", "+"):
            char, _ = self.peek()
            self.index += 1
            result = _repeat(result, star=char == "*")
        return result

    def atom(self) -> Pattern:
        char, offset = self.peek()
        self.index += 1
        if char == "-":
            return Epsilon()
        if char != "(":
            return Symbol(char)
        if self.depth >= MAX_NESTING:
            raise PatternError(f"parentheses are nested deeper than {MAX_NESTING} levels", offset)
        self.depth += 1
        inner = self.union()
        self.depth -= 1
        if self.peek()[0] != ")":
            raise PatternError("unbalanced '('", offset)
        self.index += 1
        return inner


def _repeat(inner: Pattern, *, star: bool) -> Pattern:
    """``inner*`` or ``inner+``, collapsing stacked repetitions."""
    if isinstance(inner, Star):
        return inner
    if isinstance(inner, Plus):
        return Star(inner.inner) if star else inner
    return Star(inner) if star else Plus(inner)


def parse_pattern(text: str) -> Pattern:
    """Parse a pattern; raise :class:`PatternError` (with an offset into ``text``) if invalid."""
    return _Parser(text).parse()


def _letters(pattern: Pattern) -> frozenset[str]:
    if isinstance(pattern, Symbol):
        return frozenset((pattern.letter,))
    if isinstance(pattern, Epsilon):
        return frozenset()
    if isinstance(pattern, (Star, Plus)):
        return _letters(pattern.inner)
    children = pattern.parts if isinstance(pattern, Concat) else pattern.options
    result: frozenset[str] = frozenset()
    for child in children:
        result |= _letters(child)
    return result


def placeholders(pattern: Pattern) -> frozenset[str]:
    """The placeholder letters (uppercase) of a pattern."""
    return frozenset(letter for letter in _letters(pattern) if letter.isupper())


def event_letters(pattern: Pattern) -> frozenset[str]:
    """The event letters (lowercase) of a pattern."""
    return frozenset(letter for letter in _letters(pattern) if letter.islower())


_UNION, _CONCAT, _POSTFIX = 0, 1, 2


def _precedence(pattern: Pattern) -> int:
    if isinstance(pattern, Union):
        return _UNION if len(pattern.options) > 1 else _precedence_of_single(pattern.options)
    if isinstance(pattern, Concat):
        return _CONCAT if len(pattern.parts) > 1 else _precedence_of_single(pattern.parts)
    return _POSTFIX


def _precedence_of_single(children: tuple[Pattern, ...]) -> int:
    return _precedence(children[0]) if children else _POSTFIX


def _text_at(pattern: Pattern, minimum: int, parent: type[Concat] | type[Union] | None) -> str:
    """Text of ``pattern``, parenthesised if it binds looser than ``minimum`` or would merge."""
    text = to_text(pattern)
    merges = parent is not None and isinstance(pattern, parent) and len(_children(pattern)) > 1
    if _precedence(pattern) < minimum or merges:
        return f"({text})"
    return text


def _children(pattern: Pattern) -> tuple[Pattern, ...]:
    if isinstance(pattern, Concat):
        return pattern.parts
    if isinstance(pattern, Union):
        return pattern.options
    return ()


def to_text(pattern: Pattern) -> str:
    """Canonical text of a pattern, with the fewest parentheses; it parses back to the pattern.

    Trees the parser never builds are printed faithfully where the syntax allows: an empty
    concatenation prints as ``-``, a one-element concatenation or union as its element, and a
    nested concatenation or union in parentheses. An empty union has no text and raises
    :class:`PatternError`.
    """
    if isinstance(pattern, Symbol):
        return pattern.letter
    if isinstance(pattern, Epsilon):
        return "-"
    if isinstance(pattern, Star):
        return _text_at(pattern.inner, _POSTFIX, None) + "*"
    if isinstance(pattern, Plus):
        return _text_at(pattern.inner, _POSTFIX, None) + "+"
    if isinstance(pattern, Concat):
        if not pattern.parts:
            return "-"
        if len(pattern.parts) == 1:
            return to_text(pattern.parts[0])
        return "".join(_text_at(part, _POSTFIX, Concat) for part in pattern.parts)
    if not pattern.options:
        raise PatternError("an empty union has no text", 0)
    if len(pattern.options) == 1:
        return to_text(pattern.options[0])
    return "|".join(_text_at(option, _CONCAT, Union) for option in pattern.options)


def substitute(pattern: Pattern, mapping: dict[str, str]) -> Pattern:
    """Replace placeholder letters (uppercase) by the letters ``mapping`` gives them.

    Placeholders missing from ``mapping`` and event letters are kept as they are.
    """
    if isinstance(pattern, Symbol):
        if pattern.letter.isupper() and pattern.letter in mapping:
            return Symbol(mapping[pattern.letter])
        return pattern
    if isinstance(pattern, Epsilon):
        return pattern
    if isinstance(pattern, Star):
        return Star(substitute(pattern.inner, mapping))
    if isinstance(pattern, Plus):
        return Plus(substitute(pattern.inner, mapping))
    if isinstance(pattern, Concat):
        return Concat(tuple(substitute(part, mapping) for part in pattern.parts))
    return Union(tuple(substitute(option, mapping) for option in pattern.options))
