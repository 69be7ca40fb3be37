"""ROS graph-name validation for topic, service and parameter names.

The rules are those of the ROS 1 wiki page "Names": a name is non-empty, starts with a letter,
``/`` or ``~``, continues with letters, digits, ``_`` and ``/``, has no empty token (``//``) and
no trailing ``/``. imrosc adds its own rules on top:

* the root namespace ``/`` alone names nothing a configuration can refer to;
* private names (``~x``) have no meaning in a configuration, which belongs to no node;
* relative names are accepted but resolved against the root namespace (a warning);
* names that ROS 1 accepts but ROS 2 rejects (a token starting with a digit, or ``__``) are
  reported so that a configuration meant for both middlewares stays portable (a warning).

Only ASCII letters and digits count: ROS names are ASCII.
"""

from __future__ import annotations

import string
from dataclasses import dataclass

__all__ = [
    "BAD_NAME",
    "RELATIVE_NAME",
    "ROS2_INCOMPATIBLE_NAME",
    "NameProblem",
    "check_graph_name",
    "is_global_name",
    "resolve_name",
]

BAD_NAME = "bad-name"
RELATIVE_NAME = "relative-name"
ROS2_INCOMPATIBLE_NAME = "ros2-incompatible-name"

_LETTERS = frozenset(string.ascii_letters)
_DIGITS = frozenset(string.digits)
_FOLLOWING = _LETTERS | _DIGITS | {"_", "/"}
_SHOWN_LENGTH = 60


@dataclass(frozen=True)
class NameProblem:
    """One problem with a name: a diagnostic code, a message, and the 0-based offset in the name."""

    code: str
    message: str
    offset: int


def _show(name: str) -> str:
    """Quote a name for a message: printable, escaped, and not absurdly long."""
    if len(name) > _SHOWN_LENGTH:
        name = name[: _SHOWN_LENGTH - 3] + "..."
    if name.isprintable() and "'" not in name and "\\" not in name:
        return f"'{name}'"
    return repr(name)


def _syntax_problem(name: str, kind: str) -> NameProblem | None:
    """The first violation of the ROS 1 naming rules (plus imrosc's), or None."""
    shown = f"{kind} name {_show(name)}"
    if not name:
        return NameProblem(BAD_NAME, f"{kind} name is empty", 0)
    first = name[0]
    if first == "~":
        message = f"{shown} is private; private names are not allowed in a configuration"
        return NameProblem(BAD_NAME, message, 0)
    if first not in _LETTERS and first != "/":
        message = f"{shown} must start with a letter or '/', not {first!r}"
        return NameProblem(BAD_NAME, message, 0)
    if name == "/":
        message = f"{shown} is the root namespace, not a {kind} name"
        return NameProblem(BAD_NAME, message, 0)
    for index in range(1, len(name)):
        char = name[index]
        if char not in _FOLLOWING:
            message = f"{shown} contains {char!r}; only letters, digits, '_' and '/' are allowed"
            return NameProblem(BAD_NAME, message, index)
        if char == "/" and name[index - 1] == "/":
            return NameProblem(BAD_NAME, f"{shown} has an empty token", index)
    if name.endswith("/"):
        return NameProblem(BAD_NAME, f"{shown} ends with '/'", len(name) - 1)
    return None


def _ros2_problem(name: str, kind: str) -> NameProblem | None:
    """The first token that ROS 2 rejects in a name that ROS 1 accepts, or None."""
    shown = f"{kind} name {_show(name)}"
    start = 0
    for token in name.split("/"):
        if token and token[0] in _DIGITS:
            message = f"{shown} has a token starting with a digit, which ROS 2 rejects"
            return NameProblem(ROS2_INCOMPATIBLE_NAME, message, start)
        double = token.find("__")
        if double >= 0:
            message = f"{shown} contains '__', which ROS 2 rejects"
            return NameProblem(ROS2_INCOMPATIBLE_NAME, message, start + double)
        start += len(token) + 1
    return None


def check_graph_name(name: str, kind: str) -> list[NameProblem]:
    """Check a topic, service or parameter name (``kind`` names which, for messages).

    A name that breaks the rules gives exactly one ``bad-name`` problem (the first one found).
    A valid name gives a ``relative-name`` problem when it does not start with ``/`` and a
    ``ros2-incompatible-name`` problem when ROS 2 would reject it; otherwise no problem.
    """
    bad = _syntax_problem(name, kind)
    if bad is not None:
        return [bad]
    problems: list[NameProblem] = []
    if not is_global_name(name):
        message = (
            f"{kind} name {_show(name)} is relative; imrosc resolves it against the root "
            f"namespace as {_show(resolve_name(name))}"
        )
        problems.append(NameProblem(RELATIVE_NAME, message, 0))
    ros2 = _ros2_problem(name, kind)
    if ros2 is not None:
        problems.append(ros2)
    return problems


def is_global_name(name: str) -> bool:
    """Whether the name is global (starts with ``/``)."""
    return name.startswith("/")


def _normalise_namespace(namespace: str) -> str:
    """A namespace as ``/a/b`` (root: ``/``): leading slash added, trailing slashes removed."""
    stripped = namespace.strip("/")
    return "/" + stripped if stripped else "/"


def resolve_name(name: str, namespace: str = "/") -> str:
    """Resolve a name against a namespace, as ROS does.

    Global names are returned unchanged; relative names are appended to ``namespace``; private
    names (``~x``) are appended to ``namespace`` taken as the node's own name. The function does
    not validate: call :func:`check_graph_name` first. It never raises.
    """
    if is_global_name(name):
        return name
    base = _normalise_namespace(namespace)
    rest = name[1:].lstrip("/") if name.startswith("~") else name
    if not rest:
        return base
    return base + rest if base == "/" else f"{base}/{rest}"
