"""The family catalog is the one list of families: the job schema, the monitor's family
sets and inference's groups follow it, and the compiled kernel never clears a sample of a
family it does not know."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from imrosc.infer.registry import FAMILY_GROUPS
from imrosc.runtime import checks as checks_module
from imrosc.runtime import families
from imrosc.runtime.checks import Checks

SCHEMA = Path(checks_module.__file__).parents[1] / "backends" / "schemas" / "job.schema.json"


def family_enum(schema: Any) -> list[str] | None:
    """The enum of the job schema's ``families`` items."""
    if isinstance(schema, dict):
        if "families" in schema.get("properties", {}):
            return list(schema["properties"]["families"]["items"]["enum"])
        for value in schema.values():
            found = family_enum(value)
            if found is not None:
                return found
    elif isinstance(schema, list):
        for value in schema:
            found = family_enum(value)
            if found is not None:
                return found
    return None


def test_the_job_schema_lists_the_catalog() -> None:
    assert family_enum(json.loads(SCHEMA.read_text())) == list(families.NAMES)


def test_every_family_has_a_group_and_a_point_kind() -> None:
    assert set(FAMILY_GROUPS) == set(families.GROUPS)
    assert set().union(*FAMILY_GROUPS.values()) == set(families.NAMES)
    for family in families.CATALOG:
        assert family.points <= set(families.POINT_KINDS)
        # a family no point kind instantiates is learnt by classification: a detector
        assert family.points or family.check == "score"
        assert family.check in ("value", "window", "event", "score")
        assert not family.compiled or family.check == "value"


def test_points_get_their_families_in_catalog_order() -> None:
    publish = families.for_point(families.PUBLISH)
    assert publish[0] == families.BOUNDS and publish[-1] == families.POLYGON
    assert families.for_point(families.PARAM) == ("bounds", "one-of", "string-one-of")
    assert families.for_point(families.TEMPORAL) == ("interval",)
    assert families.for_point(families.TEMPORAL, patterns=True) == ("interval", "pattern")


BOUNDED = {
    "id": "i1",
    "family": "bounds",
    "kind": "range",
    "point": "p",
    "variables": ["x"],
    "params": {"min": 0.0, "max": 1.0},
    "text": "0 <= x <= 1",
}


@pytest.mark.parametrize("known", [True, False], ids=["known", "unknown to the kernel"])
def test_the_kernel_is_used_only_for_families_it_knows(
    known: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    compiled: list[Any] = []
    monkeypatch.setattr(checks_module, "numba_module", object)
    monkeypatch.setattr(
        checks_module, "compile_checks", lambda tables, size: compiled.append(tables)
    )
    if not known:
        monkeypatch.setattr(checks_module, "COMPILED", frozenset({families.POLYGON}))
    checks = Checks([BOUNDED], {"x": 0}, {})
    assert bool(compiled) is known
    assert checks.numeric_families() == {families.BOUNDS}
