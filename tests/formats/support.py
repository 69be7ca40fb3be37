"""What the format tests share."""

from __future__ import annotations

from typing import Any


def same_keys(typed: Any, node: dict[str, Any]) -> None:
    """A typed dictionary and a schema object: the same keys, the same required."""
    assert set(typed.__annotations__) == set(node["properties"]), typed.__name__
    assert set(typed.__required_keys__) == set(node["required"]), typed.__name__
