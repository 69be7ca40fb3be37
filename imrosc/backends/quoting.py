"""Quoting helpers of the backends: text from a configuration or an invariants file becomes a
Python literal, a CMake word or comment text (``#`` or XML) that cannot end its comment,
whatever it holds. Templates only format; every such value goes through one of these
filters (:func:`environment`), and the launch rewriters write their banner comments with
:func:`xml_comment`."""

from __future__ import annotations

import json
import math
import re
import textwrap
from typing import Any

from jinja2 import ChoiceLoader, Environment, PackageLoader, StrictUndefined, select_autoescape
from markupsafe import Markup


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


def xml_comment(text: str) -> str:
    """``text`` as the body of an XML comment: one line, no ``--``, padded with spaces.

    >>> xml_comment("a--b\\nc")
    ' a- -b\\\\nc '
    """
    shown = text.encode("unicode_escape").decode("ascii")
    while "--" in shown:
        shown = shown.replace("--", "- -")
    return f" {shown} "


def xml_comment_filter(text: Any) -> Markup:
    """The body of an XML comment (already safe: no ``--``, one line)."""
    return Markup(xml_comment(str(text)))


_CMAKE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def cmake_name(text: Any) -> str:
    """A CMake word that needs no quoting (package and script names are checked before)."""
    if not isinstance(text, str) or not _CMAKE_NAME.fullmatch(text):
        raise ValueError(f"{text!r} is not a plain CMake name")
    return text


def environment(packages: tuple[str, ...], xml_extensions: tuple[str, ...]) -> Environment:
    """The template environment of backends' packages (their ``templates/`` folders, the
    first that holds a name wins): strict, templates ending in ``xml_extensions``
    autoescaped, with the quoting filters."""
    env = Environment(
        loader=ChoiceLoader([PackageLoader(package, "templates") for package in packages]),
        autoescape=select_autoescape(enabled_extensions=xml_extensions, default=False),
        undefined=StrictUndefined,
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["py"] = py_literal
    env.filters["hash_comment"] = hash_comment
    env.filters["xml_comment"] = xml_comment_filter
    env.filters["cmake_name"] = cmake_name
    return env
