"""The family catalog is the one list of families: the job schema, the monitor's family
sets and inference's groups follow it, inference's state builders and the runtime's check
collectors are registered against it, and the compiled kernel never clears a sample of a
family it does not know."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from imrosc.infer import builders
from imrosc.infer.registry import FAMILY_GROUPS
from imrosc.runtime import checks as checks_module
from imrosc.runtime import families
from imrosc.runtime.checks import Checks

SCHEMA = Path(checks_module.__file__).parents[1] / "backends" / "schemas" / "job.schema.json"


def family_items(schema: Any) -> Any:
    """The job schema's ``families`` items (None if it has none)."""
    if isinstance(schema, dict):
        if "families" in schema.get("properties", {}):
            return schema["properties"]["families"]["items"]
        values = list(schema.values())
    elif isinstance(schema, list):
        values = schema
    else:
        return None
    for value in values:
        found = family_items(value)
        if found is not None:
            return found
    return None


def family_enum(schema: Any) -> list[str] | None:
    """The enum of the job schema's ``families`` items."""
    items = family_items(schema)
    return None if items is None else list(items["enum"])


def test_the_job_schema_lists_the_catalog() -> None:
    """The schema's family list is the catalog's; ``IMROSC_UPDATE_GOLDEN=1`` writes it."""
    schema = json.loads(SCHEMA.read_text(encoding="utf-8"))
    if os.environ.get("IMROSC_UPDATE_GOLDEN") == "1":
        family_items(schema)["enum"] = list(families.NAMES)
        SCHEMA.write_text(json.dumps(schema, indent=2, ensure_ascii=False) + "\n", "utf-8")
    assert family_enum(schema) == list(families.NAMES)


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


def test_a_family_the_kernel_does_not_know_is_checked_by_numpy(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A kernel that clears every sample stands in for numba: with bounds unknown to it, a
    sample out of bounds is still found (numpy checks it), never cleared unchecked."""
    monkeypatch.setattr(checks_module, "numba_module", object)
    monkeypatch.setattr(checks_module, "compile_checks", lambda tables, size: lambda *a: True)
    row = np.array([2.0])
    cleared = Checks([BOUNDED], {"x": 0}, {})
    assert cleared.compiled and cleared.check(0.0, "p", row) == []  # the stand-in clears all
    monkeypatch.setattr(checks_module, "COMPILED", families.COMPILED - {families.BOUNDS})
    checked = Checks([BOUNDED], {"x": 0}, {})
    assert not checked.compiled
    (violation,) = checked.check(0.0, "p", row)
    assert violation.invariant == "i1"


def test_every_value_family_has_one_check_collector() -> None:
    values = {f.name for f in families.CATALOG if f.check == "value"}
    assert set(checks_module.COLLECTORS) == values
    with pytest.raises(ValueError, match="no value family"):
        checks_module.collects(families.FREQUENCY)
    with pytest.raises(ValueError, match="no value family"):
        checks_module.collects("cubic")


def test_every_inferred_family_has_one_state_builder() -> None:
    inferred = {f.name for f in families.CATALOG if f.points}
    assert builders.registered() == inferred
    with pytest.raises(ValueError, match="not in the family catalog"):
        builders.builds("cubic")
    with pytest.raises(ValueError, match="learnt by classification"):
        builders.builds(families.DETECTOR)
    with pytest.raises(ValueError, match="has a state builder already"):
        builders.builds(families.BOUNDS)(lambda point, tunables, enabled: [])


def test_a_family_the_kernel_does_not_know_is_never_compiled_however_held(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A value family added to the catalog and the checks but to none of the held lists
    :meth:`Checks.numeric_families` reads is still kept from the compiled kernel."""
    cubic = families.Family("cubic", "default", frozenset({families.PUBLISH}), "value")
    monkeypatch.setitem(families.FAMILIES, "cubic", cubic)
    monkeypatch.setitem(checks_module.COLLECTORS, "cubic", lambda held, inv: None)
    monkeypatch.setattr(checks_module, "numba_module", object)
    monkeypatch.setattr(checks_module, "compile_checks", lambda tables, size: lambda *a: True)
    plain = Checks([BOUNDED], {"x": 0}, {})
    assert plain.families == {families.BOUNDS} and plain.compiled
    held = Checks([BOUNDED, dict(BOUNDED, id="i2", family="cubic")], {"x": 0}, {})
    assert held.families == {families.BOUNDS, "cubic"}
    assert held.numeric_families() == {families.BOUNDS} and not held.compiled
