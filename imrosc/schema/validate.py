"""Structural validation against ``grammar/imros.xsd`` (shipped as ``imrosc/schema/imros.xsd``).

Each xmlschema error becomes one diagnostic with a stable code and the exact position of the
offending element, attribute or text.
"""

from __future__ import annotations

import functools
import importlib.resources
import re

import xmlschema
from lxml import etree
from xmlschema.validators.exceptions import (
    XMLSchemaChildrenValidationError,
    XMLSchemaValidationError,
)

from imrosc.diagnostics import Diagnostic, make
from imrosc.schema.loader import LoadedConfig

_MISSING_ATTRIBUTE = re.compile(r"missing required attribute '([^']+)'")
_UNKNOWN_ATTRIBUTE = re.compile(r"'([^']+)' attribute not allowed")
_BAD_ATTRIBUTE = re.compile(r"^attribute ([^=\s]+)=")


def grammar_text() -> bytes:
    """The bytes of the shipped grammar."""
    return importlib.resources.files("imrosc.schema").joinpath("imros.xsd").read_bytes()


@functools.cache
def grammar() -> xmlschema.XMLSchema10:
    """The compiled grammar (loaded once per process)."""
    source = importlib.resources.files("imrosc.schema").joinpath("imros.xsd")
    with importlib.resources.as_file(source) as path:
        return xmlschema.XMLSchema10(str(path))


def _clean(reason: str) -> str:
    reason = reason.strip().rstrip(".")
    return reason[:1].lower() + reason[1:]


def _diagnose(config: LoadedConfig, error: XMLSchemaValidationError) -> Diagnostic:
    element = error.elem if isinstance(error.elem, etree._Element) else config.root
    reason = _clean(error.reason or str(error))
    line, column = config.element_position(element)
    if isinstance(error, XMLSchemaChildrenValidationError):
        child = error.invalid_child
        if isinstance(child, etree._Element):
            line, column = config.element_position(child)
            where = f"<{child.tag}> is not allowed in <{element.tag}>"
            return make(config.path, line, column, "unexpected-element", where)
        expected = ", ".join(
            f"<{e.name}>" for e in error.expected or () if getattr(e, "name", None)
        )
        message = f"<{element.tag}> is incomplete" + (f": expected {expected}" if expected else "")
        return make(config.path, line, column, "missing-element", message)
    if error.validator is grammar() or "is not an element of the schema" in reason:
        message = f"root element is <{element.tag}>; an imROS configuration starts with <imROS>"
        return make(config.path, line, column, "unknown-root", message)
    if found := _MISSING_ATTRIBUTE.search(reason):
        message = f"<{element.tag}> needs attribute '{found.group(1)}'"
        return make(config.path, line, column, "missing-attribute", message)
    if found := _UNKNOWN_ATTRIBUTE.search(reason):
        line, column = config.attribute_position(element, found.group(1), value=False)
        message = f"<{element.tag}> has no attribute '{found.group(1)}'"
        return make(config.path, line, column, "unknown-attribute", message)
    if found := _BAD_ATTRIBUTE.search(reason):
        name = found.group(1)
        line, column = config.attribute_position(element, name)
        value = element.get(name, "")
        detail = reason.split(":", 1)[1].strip() if ":" in reason else reason
        message = f"invalid value '{value}' for attribute '{name}' of <{element.tag}>: {detail}"
        return make(config.path, line, column, "invalid-value", message)
    line, column = config.text_position(element)
    return make(config.path, line, column, "invalid-value", f"<{element.tag}>: {reason}")


def validate_structure(config: LoadedConfig) -> list[Diagnostic]:
    """Validate the tree against the grammar; an empty list means it conforms."""
    schema = grammar()
    return [_diagnose(config, error) for error in schema.iter_errors(config.root.getroottree())]
