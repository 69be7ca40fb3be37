"""Quoting filters of the backends' templates: text from a configuration or an invariants
file becomes a Python literal or comment text that cannot end its comment, whatever it
holds. Templates only format; every such value goes through one of these."""

from __future__ import annotations

import json
import math
import textwrap
from typing import Any

from jinja2 import Environment, PackageLoader, StrictUndefined, select_autoescape
from markupsafe import Markup

from imrosc.backends import launch


def py_literal(value: Any) -> str:
    """A Python literal of a str, int, finite float, bool or None, on one line, that Python
    reads back as the same value whatever the text holds: JSON for a string (ASCII, every
    quote and control character escaped), ``repr`` for the rest."""
    if isinstance(value, str):
        return json.dumps(value)
    if value is None or isinstance(value, bool | int):
        return repr(value)
    if isinstance(value, float) and math.isfinite(value):
        return repr(value)
    raise ValueError(f"no literal for {value!r}")


COMMENT_WIDTH = 96


def hash_comment(text: Any) -> str:
    """``text`` as ``#`` comment lines: non-printable and non-ASCII characters escaped (so no
    text can end the comment), wrapped to the line length (a long path is cut)."""
    shown = str(text).encode("unicode_escape").decode("ascii")
    lines = textwrap.wrap(shown, COMMENT_WIDTH, break_long_words=True, break_on_hyphens=False) or [
        ""
    ]
    return "\n".join(["# " + lines[0], *("#   " + line for line in lines[1:])])


def xml_comment_filter(text: Any) -> Markup:
    """The body of an XML comment (already safe: no ``--``, one line)."""
    return Markup(launch.xml_comment(str(text)))


def environment(package: str, xml_extensions: tuple[str, ...]) -> Environment:
    """The template environment of a backend's package (its ``templates/`` folder): strict,
    templates ending in ``xml_extensions`` autoescaped, with the quoting filters."""
    env = Environment(
        loader=PackageLoader(package, "templates"),
        autoescape=select_autoescape(enabled_extensions=xml_extensions, default=False),
        undefined=StrictUndefined,
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["py"] = py_literal
    env.filters["hash_comment"] = hash_comment
    env.filters["xml_comment"] = xml_comment_filter
    return env
