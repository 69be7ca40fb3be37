"""The files of a generated package that its nodes read at start, and the monitor spec's
format (:class:`SpecDocument`).

A package's Python package holds its generated files (the monitor spec ``spec.json``, the
recorder spec ``recorder.json``) beside ``imrosc/``, the copy of imrosc's robot-side
packages; :func:`package_folder` finds it from this module's own place, the same in both
backends' layouts and in imrosc's source tree. Python 3.8 syntax, standard library only.
"""

from __future__ import annotations

import json
import os
from typing import Any, Collection, Dict, List, Mapping, Optional, TypedDict, Union, cast

SPEC_FILE = "spec.json"
"""The monitor spec of a package (what the monitor node watches and does)."""
SPEC_FORMAT = "imrosc-monitor"
SPEC_VERSION = 1
INVARIANTS_FORMAT = "imrosc-invariants"


class SpecTopic(TypedDict):
    """A topic the monitor subscribes to: its ROS 1 and ROS 2 types (``None``: asked of the
    graph at run time) and, for a blocked topic, the relay it publishes on (``/m/<topic>``)."""

    name: str
    type: Optional[str]
    ros2_type: Optional[str]
    relay: Optional[str]


class SpecService(TypedDict):
    """A service the monitor relays: served on ``relay``, forwarded to ``name``; ``block``:
    a call that breaks an invariant is refused (else only checked)."""

    name: str
    relay: str
    block: bool


class SpecAction(TypedDict):
    """An action: publish ``value`` on ``destination`` or call the service with it."""

    target: str
    name: str
    destination: str
    type: Optional[str]
    ros2_type: Optional[str]
    value: Mapping[str, Any]


SpecDocument = TypedDict(
    "SpecDocument",
    {
        "$comment": str,
        "format": str,
        "version": int,
        "project": str,
        "package": str,
        "node": str,
        "watchdog": str,
        "namespace": str,
        "period": float,
        "topics": List[SpecTopic],
        "services": List[SpecService],
        "actions": Dict[str, SpecAction],
        "violations": Dict[str, List[str]],
        "params": List[str],
        "alarms": Dict[str, Union[int, float]],
    },
)
"""A monitor's ``spec.json`` (``imrosc/backends/schemas/spec.schema.json`` is its JSON
schema; the monitor backends write it, the monitor and watchdog nodes read it):
``violations`` maps an invariant id or point key to the actions it triggers, ``params`` are
the parameters the node asks for, ``alarms`` the ``<monitor>``'s overrides of the alarm rule."""


def package_folder() -> str:
    """The folder of the Python package that carries this copy of imrosc (``imrosc/`` is
    copied into it, beside the package's generated files)."""
    return os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))


def load_spec(directory: Optional[str] = None, name: str = SPEC_FILE) -> Dict[str, Any]:
    """The JSON object of a generated file of the package (``spec.json``, or ``name``) in
    ``directory`` (default: :func:`package_folder`)."""
    with open(os.path.join(directory or package_folder(), name), encoding="utf-8") as stream:
        spec: Dict[str, Any] = json.load(stream)
    return spec


def load_monitor_spec(directory: Optional[str] = None) -> SpecDocument:
    """The package's monitor spec (``spec.json`` in ``directory``, default
    :func:`package_folder`), as the monitor backend wrote it."""
    return cast(SpecDocument, load_spec(directory))


class InvariantsError(ValueError):
    """An invariants file the monitor cannot check (the message names the file, or the
    node's ``main`` adds it)."""


ENGINE_ERRORS = (KeyError, IndexError, TypeError, ValueError, OverflowError, AttributeError)
"""What building the engine from an invariants document of the right shape but wrong
contents raises (a file edited by hand: keys or values it lacks)."""

_TOP = {"topics": dict, "points": dict, "invariants": list}
_POINT = {"kind": str, "variables": list}
_VARIABLE = {"name": str, "type": str}
_INVARIANT = {
    "id": str,
    "family": str,
    "kind": str,
    "point": str,
    "variables": list,
    "params": dict,
    "text": str,
}
_JSON = {str: "string", dict: "object", list: "array", int: "integer"}


def _fields(item: Any, shape: Mapping[str, type], where: str) -> Optional[str]:
    if not isinstance(item, dict):
        return f"{where}: not an object"
    for key, kind in shape.items():
        if key not in item:
            return f"{where}: missing '{key}'"
        if not isinstance(item[key], kind) or isinstance(item[key], bool):
            name = _JSON[kind]
            return f"{where}.{key}: not {'an' if name[0] in 'aeiou' else 'a'} {name}"
    return None


def _family(invariant: Mapping[str, Any], known: Collection[str], where: str) -> Optional[str]:
    family = invariant.get("family")
    return None if family in known else f"{where}.family: unknown family {family!r}"


def unknown_family(invariants: Any, known: Collection[str]) -> Optional[str]:
    """The first invariant of a family not ``known`` (the engine would skip it), or
    ``None``."""
    for index, invariant in enumerate(invariants):
        problem = _family(invariant, known, f"$.invariants[{index}]")
        if problem:
            return problem
    return None


def invariants_problem(document: Any, known: Optional[Collection[str]] = None) -> Optional[str]:
    """The first problem of an invariants document's shape (the keys and types the engine
    reads, every invariant's point among the points and, given the ``known`` families, its
    family among them), or ``None``: the one check of ``imrosc`` (``imrosc/invariants.py``)
    and of the monitor nodes.

    >>> invariants_problem({"topics": {}, "points": {}, "invariants": [{"id": "i1"}]})
    "$.invariants[0]: missing 'family'"
    """
    problem = _fields(document, _TOP, "$")
    for key, point in document["points"].items() if not problem else ():
        problem = _fields(point, _POINT, f"$.points.{key}")
        for index, variable in enumerate(point["variables"]) if not problem else ():
            problem = problem or _fields(variable, _VARIABLE, f"$.points.{key}.variables[{index}]")
        if problem:
            return problem
    for index, invariant in enumerate(document["invariants"]) if not problem else ():
        where = f"$.invariants[{index}]"
        problem = _fields(invariant, _INVARIANT, where)
        if not problem and invariant["point"] not in document["points"]:
            problem = f"{where}.point: no point {invariant['point']!r} in 'points'"
        if not problem and known is not None:
            problem = _family(invariant, known, where)
        if problem:
            return problem
    return problem


def load_invariants(path: str) -> Dict[str, Any]:
    """An invariants file; :class:`InvariantsError` (a ``ValueError``), one line naming the
    file and the first problem, if it cannot be read or is not one."""
    try:
        with open(path, encoding="utf-8") as stream:
            document = json.load(stream)
    except OSError as error:
        raise InvariantsError(f"{path}: cannot read: {error.strerror}") from None
    except UnicodeDecodeError:
        raise InvariantsError(f"{path}: not UTF-8 text") from None
    except json.JSONDecodeError as error:
        where = f"{path}:{error.lineno}:{error.colno}"
        raise InvariantsError(f"{where}: not JSON: {error.msg}") from None
    except (RecursionError, ValueError) as error:  # nested too deeply, an overlong integer
        raise InvariantsError(f"{path}: not JSON: {str(error).split(';')[0]}") from None
    if not isinstance(document, dict) or document.get("format") != INVARIANTS_FORMAT:
        raise InvariantsError(f"{path}: not an imrosc invariants file")
    for key in ("topics", "points", "invariants"):
        if key not in document:
            raise InvariantsError(f"{path}: missing {key!r}")
    problem = invariants_problem(document)
    if problem:
        raise InvariantsError(f"{path}: malformed: {problem}")
    return document
