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
from typing import Any, Dict, List, Mapping, Optional, TypedDict, Union, cast

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


def load_invariants(path: str) -> Dict[str, Any]:
    """An invariants file; ``ValueError`` with the reason if it is not one."""
    with open(path, encoding="utf-8") as stream:
        document = json.load(stream)
    if not isinstance(document, dict) or document.get("format") != INVARIANTS_FORMAT:
        raise ValueError(f"{path}: not an imrosc invariants file")
    for key in ("topics", "points", "invariants"):
        if key not in document:
            raise ValueError(f"{path}: missing {key!r}")
    return document
