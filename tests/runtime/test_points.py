"""The pairing record of a program point (``imrosc.runtime.points``): what inference writes
is what the engine and the backends read back."""

from __future__ import annotations

import json

from imrosc.runtime import Engine
from imrosc.runtime.points import Filter, Pairing
from tests.runtime.support import var

DECLARED = Filter(
    "1", "/state", {"op": "==", "left": "x", "right": 4}, ((("data",), "state.data"),)
)
DISCOVERED = Filter(variable="cmd.mode", value="land")


def test_a_pairing_reads_back_what_it_writes() -> None:
    pairing = Pairing(("/pose",), ("/gain",), (("A", "publish", "/cmd"),), (DECLARED, DISCOVERED))
    text = json.dumps(pairing.to_json())
    assert Pairing.from_json(json.loads(text)) == pairing
    assert json.loads(text)["filter"] == [
        {
            "id": "1",
            "topic": "/state",
            "expression": DECLARED.expression,
            "fields": [[["data"], "state.data"]],
        },
        {"variable": "cmd.mode", "value": "land"},
    ]
    assert DECLARED.declared and not DISCOVERED.declared


def test_a_point_without_pairing_keys_pairs_nothing() -> None:
    assert Pairing.from_json({"kind": "param", "variables": []}) == Pairing()


def test_the_engine_pairs_a_point_as_its_record_says() -> None:
    pairing = Pairing(("/b",), ("/gain",), (), (DISCOVERED,))
    variables = [var("a.v", "v"), var("b.w", "w", trigger=False), var("/gain", "", trigger=False)]
    document = {
        "topics": {"/a": {"variables": [var("a.v", "v")]}, "/b": {"variables": [var("b.w", "w")]}},
        "points": {
            "p": {"kind": "publish", "trigger": "/a", "variables": variables, **pairing.to_json()}
        },
        "invariants": [],
    }
    point = Engine(document).points["p"]
    assert (point.inputs, point.params, point.filters) == (("/b",), ("/gain",), (DISCOVERED,))
