"""The example documents under ``fixtures/``: each kind of result document, by hand."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

FIXTURES = Path(__file__).parent / "fixtures"
DOCUMENTS = ["replay", "replay_empty", "classify", "classify_onsets", "compare", "stability"]


def load(name: str) -> dict[str, Any]:
    """The example document ``fixtures/<name>.json``, read anew (tests may change it)."""
    document: dict[str, Any] = json.loads((FIXTURES / f"{name}.json").read_text())
    return document
