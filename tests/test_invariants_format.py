"""The invariants file's three descriptions agree: the typed dictionaries
(``imrosc.invariants.InvariantsDocument``), the JSON schema shipped beside the module and the
reader's own check; every invariants file imrosc ships or writes follows the schema."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest

from imrosc import invariants
from imrosc.onboard import files
from imrosc.runtime import families, points
from tests.runtime.support import infer, planted

ROOT = Path(__file__).resolve().parent.parent
SCHEMA_FILE = ROOT / "imrosc" / invariants.SCHEMA
SHIPPED = sorted(
    [
        ROOT / "examples" / "crazyflie.inv",
        ROOT / "tests" / "live" / "casestudy" / "landing.refined.inv",
        *(ROOT / "tests" / "fixtures").rglob("*.inv"),
    ]
)


def test_the_schema_is_a_schema_and_lists_the_catalog() -> None:
    """``IMROSC_UPDATE_GOLDEN=1`` writes the catalog's families and point kinds into it."""
    schema = invariants.schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    definitions = schema["$defs"]
    if os.environ.get("IMROSC_UPDATE_GOLDEN") == "1":
        definitions["invariant"]["properties"]["family"]["enum"] = list(families.NAMES)
        definitions["point"]["properties"]["kind"]["enum"] = list(families.POINT_KINDS)
        SCHEMA_FILE.write_text(json.dumps(schema, indent=2, ensure_ascii=False) + "\n", "utf-8")
    assert definitions["invariant"]["properties"]["family"]["enum"] == list(families.NAMES)
    assert definitions["point"]["properties"]["kind"]["enum"] == list(families.POINT_KINDS)


def test_the_typed_dictionaries_name_the_schema_s_keys() -> None:
    schema = invariants.schema()
    definitions = schema["$defs"]
    top = invariants.InvariantsDocument.__annotations__
    assert set(top) == set(schema["properties"])
    assert set(invariants.InvariantsDocument.__required_keys__) - {"$comment"} == set(
        schema["required"]
    )
    assert set(invariants.InvariantEntry.__annotations__) == set(
        definitions["invariant"]["properties"]
    )
    assert set(invariants.VariableEntry.__annotations__) == set(
        definitions["variable"]["properties"]
    )
    assert set(invariants.Support.__annotations__) == set(definitions["support"]["required"])
    point = invariants.PointEntry
    assert set(point.__annotations__) == set(definitions["point"]["properties"])
    assert set(point.__required_keys__) == set(definitions["point"]["required"])
    assert set(points.FilterEntry.__annotations__) == set(definitions["filter"]["properties"])


def test_the_reader_checks_the_keys_the_schema_requires() -> None:
    definitions = invariants.schema()["$defs"]
    # the reader's shape check (imrosc.onboard.files, shared with the monitor nodes)
    assert set(files._INVARIANT) == set(definitions["invariant"]["required"])
    assert set(files._POINT) == set(definitions["point"]["required"])
    assert set(files._TOP) | {"format", "version"} == set(invariants.schema()["required"])


def _conforms(document: Any) -> None:
    errors = list(jsonschema.Draft202012Validator(invariants.schema()).iter_errors(document))
    assert not errors, errors[0]


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_shipped_invariants_file_follows_the_schema(path: Path) -> None:
    _conforms(invariants.load(path))


def test_a_document_inference_writes_follows_the_schema(tmp_path: Path) -> None:
    found = infer(planted(np.random.default_rng(3), 300), 64)
    assert {i["family"] for i in found} >= {families.BOUNDS, families.POLYGON}
    document = invariants.document(
        project="t",
        source="t.xml",
        bags=["a.bag"],
        tunables={"window": 1.0},
        topics={},
        points=[],
        invariants=[],
    )
    document["invariants"] = found
    _conforms(json.loads(invariants.dumps(document)))


def test_the_schema_refuses_what_the_reader_refuses() -> None:
    document = json.loads((ROOT / "examples" / "crazyflie.inv").read_text(encoding="utf-8"))
    document["invariants"][0]["family"] = "cubic"
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(document, invariants.schema())
    del document["invariants"][0]["family"]
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(document, invariants.schema())
