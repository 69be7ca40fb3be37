"""Exact source positions of elements, attributes and text, from a scan of the raw text.

lxml gives only a line per element, and that line is where the start tag *ends*. The
diagnostics want ``line:col`` of the start tag, of an attribute, or of a character inside a
text value, so this module scans the markup once, in document order, and pairs the start
tags it finds with the parsed elements (the n-th start tag is the n-th element of
``root.iter()``). The scan also finds a DOCTYPE before the XML parser ever sees it.

>>> index = scan('<a x="1">\\n  <b> t </b></a>')
>>> index.position(index.tags[1].start)
(2, 3)
>>> index.position(index.tags[0].attributes["x"][1])
(1, 7)
"""

from __future__ import annotations

import bisect
import re
from dataclasses import dataclass, field

_NAME = re.compile(r"[^\s/>=]+")
_SPACE = re.compile(r"\s*")
_ATTRIBUTE = re.compile(r"([^\s/>=]+)\s*=\s*(?:\"([^\"]*)\"|'([^']*)')")


class OffsetError(ValueError):
    """A problem at a place in a text value (a pattern, an expression, an action value): a
    message and the 0-based offset of the problem in the text."""

    def __init__(self, message: str, offset: int) -> None:
        super().__init__(message, offset)
        self.message = message
        self.offset = offset

    def __str__(self) -> str:
        return f"{self.message} (at offset {self.offset})"


@dataclass
class StartTag:
    """One start tag: where it begins, where its content begins, and its attributes.

    ``attributes`` maps a name to (offset of the name, offset of the value's first character).
    """

    name: str
    start: int
    content_start: int
    attributes: dict[str, tuple[int, int]] = field(default_factory=dict)


@dataclass
class SourceIndex:
    """The start tags of a document in order, a DOCTYPE if any, and line starts."""

    text: str
    tags: list[StartTag]
    doctype: int | None
    line_starts: list[int]

    def position(self, offset: int) -> tuple[int, int]:
        """1-based (line, column) of a 0-based character offset."""
        offset = max(0, min(offset, len(self.text)))
        line = bisect.bisect_right(self.line_starts, offset) - 1
        return line + 1, offset - self.line_starts[line] + 1

    def text_offset(self, tag: StartTag, relative: int = 0) -> int:
        """Offset of character ``relative`` of the text right after ``tag``.

        Exact when that text holds no entity or character references; otherwise the start
        of the text, which is still on the right element.
        """
        end = self.text.find("<", tag.content_start)
        raw = self.text[tag.content_start : end if end >= 0 else len(self.text)]
        if "&" in raw[: relative + 1]:
            return tag.content_start
        return tag.content_start + min(relative, len(raw))


def _skip(text: str, start: int, terminator: str) -> int:
    end = text.find(terminator, start)
    return len(text) if end < 0 else end + len(terminator)


def _start_tag(text: str, start: int) -> tuple[StartTag | None, int]:
    """Scan the start tag at ``text[start] == '<'``; return it and the offset after it."""
    name_match = _NAME.match(text, start + 1)
    if name_match is None:
        return None, start + 1
    tag = StartTag(name_match.group(), start, len(text))
    cursor = name_match.end()
    while cursor < len(text):
        cursor = _SPACE.match(text, cursor).end()  # type: ignore[union-attr]
        if text.startswith("/>", cursor) or text.startswith(">", cursor):
            tag.content_start = cursor + (2 if text[cursor] == "/" else 1)
            return tag, tag.content_start
        attribute = _ATTRIBUTE.match(text, cursor)
        if attribute is None:
            return tag, cursor + 1
        quoted = 2 if attribute.group(2) is not None else 3
        tag.attributes.setdefault(attribute.group(1), (attribute.start(), attribute.start(quoted)))
        cursor = attribute.end()
    return tag, cursor


def scan(text: str) -> SourceIndex:
    """Index the markup of ``text``; tolerant of malformed input (it only stops early)."""
    tags: list[StartTag] = []
    doctype: int | None = None
    line_starts = [0] + [m.end() for m in re.finditer("\n", text)]
    cursor = text.find("<")
    while 0 <= cursor < len(text):
        if text.startswith("<!--", cursor):
            cursor = _skip(text, cursor + 4, "-->")
        elif text.startswith("<![CDATA[", cursor):
            cursor = _skip(text, cursor + 9, "]]>")
        elif text.startswith("<?", cursor):
            cursor = _skip(text, cursor + 2, "?>")
        elif text.startswith("<!", cursor):
            if doctype is None and text[cursor + 2 : cursor + 9].upper() == "DOCTYPE":
                doctype = cursor
            cursor = _skip(text, cursor + 2, ">")
        elif text.startswith("</", cursor):
            cursor = _skip(text, cursor + 2, ">")
        else:
            tag, cursor = _start_tag(text, cursor)
            if tag is not None:
                tags.append(tag)
        cursor = text.find("<", cursor)
    return SourceIndex(text, tags, doctype, line_starts)
