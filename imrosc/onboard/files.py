"""The files of a generated package that its nodes read at start.

A package's Python package holds its generated files (the monitor spec ``spec.json``, the
recorder spec ``recorder.json``) beside ``imrosc/``, the copy of imrosc's robot-side
packages; :func:`package_folder` finds it from this module's own place, the same in both
backends' layouts and in imrosc's source tree. Python 3.8 syntax, standard library only.
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Optional

SPEC_FILE = "spec.json"
"""The monitor spec of a package (what the monitor node watches and does)."""
INVARIANTS_FORMAT = "imrosc-invariants"


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
