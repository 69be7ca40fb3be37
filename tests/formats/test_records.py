"""The records (``/imrosc/arch``, ``/imrosc/params``, ``/imrosc/srvs``): their typed
dictionaries (``imrosc.onboard.records``) name the keys of their JSON schema
(``imrosc/backends/schemas/records.schema.json``), and what the encoder writes and
docs/record-format.md shows follows the schema."""

from __future__ import annotations

import json
import re
from pathlib import Path

import jsonschema

from imrosc import formats
from imrosc.onboard import records
from tests.formats.support import same_keys

SCHEMA = formats.schema(formats.RECORDS_SCHEMA)
DOC = Path(__file__).resolve().parent.parent.parent / "docs" / "record-format.md"


def test_the_records_typed_dictionaries_are_their_schema() -> None:
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    definitions = SCHEMA["$defs"]
    same_keys(records.ArchRecord, definitions["arch"])
    same_keys(records.TopicEndsEntry, definitions["ends"])
    same_keys(records.ParamsRecord, definitions["params"])
    same_keys(records.CallRecord, definitions["call"])
    for name in ("arch", "params", "call"):
        assert definitions[name]["properties"]["version"]["const"] == records.VERSION


def test_what_the_encoder_writes_follows_the_schema() -> None:
    written = [
        records.arch_text({"/t": ({"/b", "/a"}, [])}, {"/s": ["/c"]}),
        records.params_text({"/a/gain": 1.5, "/a/mode": "land", "/a/list": [1, 2]}),
        records.call_text("/s", "/c", "/n", {"a": 1}, {"ok": True}, 2.5, 0.25),
        records.call_text("/s", "/unknown", "/n", {"a": 1}, None, 2.5, -1.0),
    ]
    for text in written:
        jsonschema.validate(json.loads(text), SCHEMA)


def test_the_documented_records_follow_the_schema() -> None:
    blocks = re.findall(r"```json\n(.*?)```", DOC.read_text(encoding="utf-8"), re.DOTALL)
    shown = [json.loads(block) for block in blocks if '"version"' in block]
    assert len(shown) >= 3
    for record in shown:
        jsonschema.validate(record, SCHEMA)
