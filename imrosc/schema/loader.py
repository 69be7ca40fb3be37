"""Safe loading of a configuration file: bytes, UTF-8 text, then an lxml tree.

The loader refuses, with a diagnostic and before any XML parser runs, a file over the size
cap, a file that is not UTF-8, and any document with a DOCTYPE: a configuration needs no
DTD, so XXE file reads, external DTD fetches and billion-laughs expansions never start.
The lxml parser itself is also locked down (no network, no DTD loading, no entity
resolution, no huge trees) as a second wall.
"""

from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from imrosc.diagnostics import Diagnostic, make
from imrosc.schema.positions import SourceIndex, StartTag, scan

MAX_CONFIG_BYTES = 1 << 20
"""Configurations are small; anything over 1 MiB is refused unread."""

_XML_DECLARATION = re.compile(r"<\?xml[^>]*?encoding\s*=\s*[\"']([^\"']*)[\"']")
_UTF8 = {"utf-8", "utf8"}


@dataclass
class LoadedConfig:
    """A parsed configuration with what it takes to point at any place in it."""

    path: str
    index: SourceIndex
    root: etree._Element
    tags: dict[etree._Element, StartTag] = field(default_factory=dict)

    def element_position(self, element: etree._Element) -> tuple[int, int]:
        """(line, column) of the ``<`` of the element's start tag."""
        tag = self.tags.get(element)
        if tag is None:
            line = element.sourceline
            return (line if isinstance(line, int) else 1), 1
        return self.index.position(tag.start)

    def attribute_position(
        self, element: etree._Element, name: str, *, value: bool = True, relative: int = 0
    ) -> tuple[int, int]:
        """Position of an attribute's value (or its name), plus ``relative`` characters."""
        tag = self.tags.get(element)
        if tag is None or name not in tag.attributes:
            return self.element_position(element)
        name_offset, value_offset = tag.attributes[name]
        return self.index.position(value_offset + relative if value else name_offset)

    def text_position(self, element: etree._Element, relative: int = 0) -> tuple[int, int]:
        """Position of character ``relative`` of the element's leading text."""
        tag = self.tags.get(element)
        if tag is None:
            return self.element_position(element)
        return self.index.position(self.index.text_offset(tag, relative))


def _parser() -> etree.XMLParser:
    return etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        collect_ids=False,
    )


def _read_bytes(path: Path, label: str, max_bytes: int) -> tuple[bytes | None, list[Diagnostic]]:
    try:
        info = os.stat(path)
    except OSError as error:
        return None, [make(label, 1, 1, "io-error", f"cannot read file: {error.strerror}")]
    if not stat.S_ISREG(info.st_mode):
        kind = "a directory" if stat.S_ISDIR(info.st_mode) else "not a regular file"
        return None, [make(label, 1, 1, "io-error", f"cannot read file: it is {kind}")]
    if info.st_size > max_bytes:
        return None, [_too_large(label, info.st_size, max_bytes, _head(path))]
    try:
        with open(path, "rb") as stream:
            data = stream.read(max_bytes + 1)
    except OSError as error:
        return None, [make(label, 1, 1, "io-error", f"cannot read file: {error.strerror}")]
    if len(data) > max_bytes:
        return None, [_too_large(label, len(data), max_bytes, data[:64])]
    return data, []


def _head(path: Path) -> bytes:
    """The first bytes of ``path`` (none when it cannot be read)."""
    try:
        with open(path, "rb") as stream:
            return stream.read(64)
    except OSError:
        return b""


def _too_large(label: str, size: int, max_bytes: int, head: bytes) -> Diagnostic:
    """The ``file-too-large`` error; it says so when the file is JSON, not XML (an
    invariants file given where a configuration goes, usually)."""
    message = f"file has {size} bytes or more, over the {max_bytes}-byte cap for configurations"
    if _is_json(head):
        message += f"; {_JSON}"
    return make(label, 1, 1, "file-too-large", message)


_JSON = "it is JSON, not an imROS XML configuration (an invariants file?)"


def _is_json(head: bytes) -> bool:
    """Whether bytes that should be XML begin as JSON does."""
    return head.removeprefix(b"\xef\xbb\xbf").lstrip().startswith((b"{", b"["))


def _decode(data: bytes, label: str) -> tuple[str | None, list[Diagnostic]]:
    body = data.removeprefix(b"\xef\xbb\xbf")
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as error:
        line = body.count(b"\n", 0, error.start) + 1
        line_start = body.rfind(b"\n", 0, error.start) + 1
        column = len(body[line_start : error.start].decode("utf-8", "replace")) + 1
        byte = body[error.start]
        message = f"file is not valid UTF-8: byte 0x{byte:02x} cannot start or continue a character"
        return None, [make(label, line, column, "encoding-error", message)]
    declared = _XML_DECLARATION.match(text)
    if declared and declared.group(1).lower() not in _UTF8:
        column = declared.start(1) + 1
        message = f"file declares encoding '{declared.group(1)}'; configurations must be UTF-8"
        return None, [make(label, 1, column, "encoding-error", message)]
    return text, []


def load_config(
    path: Path, *, label: str | None = None, max_bytes: int = MAX_CONFIG_BYTES
) -> tuple[LoadedConfig | None, list[Diagnostic]]:
    """Read, decode and parse ``path``; on failure return no config and the diagnostics."""
    name = label if label is not None else str(path)
    data, problems = _read_bytes(path, name, max_bytes)
    if data is None:
        return None, problems
    return parse_config_bytes(data, name)


def parse_config_bytes(data: bytes, label: str) -> tuple[LoadedConfig | None, list[Diagnostic]]:
    """Decode and parse configuration bytes already read (``label`` names them in messages)."""
    text, problems = _decode(data, label)
    if text is None:
        return None, problems
    index = scan(text)
    if index.doctype is not None:
        line, column = index.position(index.doctype)
        message = "DOCTYPE is not allowed: configurations take no DTD and no entities"
        return None, [make(label, line, column, "dtd-forbidden", message)]
    try:
        root = etree.fromstring(text.encode("utf-8"), _parser())
    except etree.XMLSyntaxError as error:
        line, column = error.position if error.position else (1, 1)
        message = (error.msg or "malformed XML").split(", line ")[0]
        message = message[:1].lower() + message[1:]
        if _is_json(data):
            message += f"; {_JSON}"
        return None, [make(label, line, column, "xml-syntax", message)]
    tree = root.getroottree()
    if getattr(tree.docinfo, "doctype", ""):  # lxml-stubs lack DocInfo.doctype
        message = "DOCTYPE is not allowed: configurations take no DTD and no entities"
        return None, [make(label, 1, 1, "dtd-forbidden", message)]
    config = LoadedConfig(label, index, root)
    elements = [e for e in root.iter() if isinstance(e.tag, str)]
    if len(elements) == len(index.tags):
        config.tags = dict(zip(elements, index.tags, strict=True))
    return config, []
