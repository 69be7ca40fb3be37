"""A monitor's ``spec.json``: its typed dictionaries (``imrosc.onboard.files``) name the keys
of its JSON schema (``imrosc/backends/schemas/spec.schema.json``), and what both monitor
backends write follows the schema."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

from imrosc import formats
from imrosc.build import build
from imrosc.onboard import files
from tests.backends.monitor_support import config_text, write_case
from tests.backends.ros2_live_support import MONITOR, SCOPE, demo_document
from tests.formats.support import same_keys

SCHEMA = formats.schema(formats.SPEC_SCHEMA)


def test_the_spec_s_typed_dictionaries_are_its_schema() -> None:
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    properties = SCHEMA["properties"]
    assert properties["format"]["const"] == files.SPEC_FORMAT
    assert properties["version"]["const"] == files.SPEC_VERSION
    same_keys(files.SpecDocument, SCHEMA)
    same_keys(files.SpecTopic, properties["topics"]["items"])
    same_keys(files.SpecService, properties["services"]["items"])
    same_keys(files.SpecAction, properties["actions"]["additionalProperties"])


@pytest.mark.parametrize("backend", ["ros1", "ros2"])
def test_the_spec_a_backend_writes_follows_the_schema(backend: str, tmp_path: Path) -> None:
    monitor = MONITOR.replace('period="0.2"', 'period="0.2" alarm_persist="2"')
    config = write_case(tmp_path, config_text(scope=SCOPE, monitor=monitor), demo_document())
    result = build(config, backend)
    assert result.ok, [d.as_text() for d in result.diagnostics]
    (name,) = [n for n in result.files if n.endswith(f"/{files.SPEC_FILE}")]
    spec = json.loads(result.files[name])
    jsonschema.validate(spec, SCHEMA)
    assert spec["actions"] and spec["services"] and spec["alarms"] == {"persist": 2}
    assert any(topic["relay"] for topic in spec["topics"])
    # what the monitor and watchdog nodes read: every key their typed dictionary names
    (tmp_path / "package").mkdir()
    (tmp_path / "package" / files.SPEC_FILE).write_bytes(result.files[name])
    loaded = files.load_monitor_spec(str(tmp_path / "package"))
    assert loaded == spec and set(loaded) == set(files.SpecDocument.__annotations__)
