"""Fixtures of the report tests."""

from __future__ import annotations

from typing import Any

import pytest

from tests.report.documents import load


@pytest.fixture
def replay_document() -> dict[str, Any]:
    """The example replay document, to change at will."""
    return load("replay")
