"""Records: canonical encoding, exact round trips, and a one-line RecordError for anything else."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.records import (
    ARCH_TOPIC,
    PARAMS_TOPIC,
    RECORD_TOPICS,
    SRVS_TOPIC,
    ArchSnapshot,
    ParamSnapshot,
    Record,
    RecordError,
    ServiceCall,
    TopicEnds,
    decode_arch,
    decode_call,
    decode_params,
    encode,
)

DOCS = Path(__file__).parent.parent / "docs" / "record-format.md"

ARCH = ArchSnapshot(
    {
        "/a/car_pose": TopicEnds(frozenset({"/a/car"}), frozenset({"/a/car_ctrl", "/a/arb"})),
        "/a/idle": TopicEnds(frozenset(), frozenset()),
    },
    {"/a/execute_task": frozenset({"/a/car"})},
)
PARAMS = ParamSnapshot({"/rate": 10, "/gps/origin": {"lat": 40.5, "lon": -96.7}, "/b": [1, "x"]})
CALL = ServiceCall(
    service="/a/execute_task",
    client="/a/car_ctrl",
    server="/a/car",
    request={"task_id": 0},
    response={"status": "ok"},
    ok=True,
    stamp=1379178103.5,
    delay=0.341,
)

Decoder = Callable[[str], Record]


def test_topics_are_the_documented_ones() -> None:
    assert (ARCH_TOPIC, PARAMS_TOPIC, SRVS_TOPIC) == RECORD_TOPICS
    assert all(topic.startswith("/imrosc/") for topic in RECORD_TOPICS)


def test_arch_encoding_is_canonical() -> None:
    text = encode(ARCH)
    assert text == (
        '{"services":{"/a/execute_task":["/a/car"]},"topics":{"/a/car_pose":{"pubs":["/a/car"],'
        '"subs":["/a/arb","/a/car_ctrl"]},"/a/idle":{"pubs":[],"subs":[]}},"version":1}'
    )


def test_params_and_call_encodings_are_canonical() -> None:
    assert encode(PARAMS) == (
        '{"params":{"/b":[1,"x"],"/gps/origin":{"lat":40.5,"lon":-96.7},"/rate":10},"version":1}'
    )
    assert encode(CALL) == (
        '{"client":"/a/car_ctrl","delay":0.341,"ok":true,"request":{"task_id":0},'
        '"response":{"status":"ok"},"server":"/a/car","service":"/a/execute_task",'
        '"stamp":1379178103.5,"version":1}'
    )


@pytest.mark.parametrize(
    ("record", "decode"),
    [(ARCH, decode_arch), (PARAMS, decode_params), (CALL, decode_call)],
    ids=["arch", "params", "call"],
)
def test_round_trip_is_exact(record: Record, decode: Decoder) -> None:
    text = encode(record)
    assert decode(text) == record
    assert encode(decode(text)) == text


def test_failed_call_has_no_response() -> None:
    failed = ServiceCall("/s", "/c", "/srv", {}, None, False, 1.0, 0.0)
    assert decode_call(encode(failed)) == failed
    assert '"response":null' in encode(failed)


def test_non_finite_parameters_round_trip() -> None:
    decoded = decode_params(encode(ParamSnapshot({"/x": math.nan, "/y": math.inf})))
    assert math.isnan(float(str(decoded.params["/x"])))
    assert decoded.params["/y"] == math.inf


def test_decoding_accepts_any_key_order_and_spacing() -> None:
    text = '{ "version": 1, "services": {}, "topics": {"/t": {"subs": ["/b"], "pubs": ["/a"]}} }'
    assert decode_arch(text) == ArchSnapshot(
        {"/t": TopicEnds(frozenset({"/a"}), frozenset({"/b"}))}, {}
    )


ARCH_OK = {"version": 1, "topics": {"/t": {"pubs": ["/a"], "subs": []}}, "services": {"/s": ["/a"]}}
CALL_OK = json.loads(encode(CALL))


def _with(document: dict[str, object], **changes: object) -> str:
    changed = {**document, **changes}
    return json.dumps({k: v for k, v in changed.items() if v is not _DROP})


_DROP = object()

BAD_ARCH = {
    "not-json": ("{version: 1}", "not JSON"),
    "truncated": ('{"version": 1, "topics": {', "not JSON"),
    "empty": ("", "not JSON"),
    "list": ("[1]", "must be a JSON object, not a list"),
    "no-version": (_with(ARCH_OK, version=_DROP), "no 'version'"),
    "version-2": (_with(ARCH_OK, version=2), "version 2"),
    "version-string": (_with(ARCH_OK, version="1"), "version '1'"),
    "version-bool": (_with(ARCH_OK, version=True), "version True"),
    "unknown-key": (_with(ARCH_OK, extra=1), "unknown key 'extra'"),
    "no-services": (_with(ARCH_OK, services=_DROP), "no 'services'"),
    "duplicate-key": ('{"version": 1, "version": 1, "topics": {}, "services": {}}', "twice"),
    "topics-list": (_with(ARCH_OK, topics=[]), "'topics' must be an object"),
    "ends-list": (_with(ARCH_OK, topics={"/t": []}), "must be an object"),
    "ends-keys": (_with(ARCH_OK, topics={"/t": {"pubs": []}}), "exactly the keys"),
    "pubs-string": (_with(ARCH_OK, topics={"/t": {"pubs": "/a", "subs": []}}), "list of node"),
    "pub-number": (_with(ARCH_OK, topics={"/t": {"pubs": [1], "subs": []}}), "pubs[0]"),
    "bad-topic": (_with(ARCH_OK, topics={"/t//x": {"pubs": [], "subs": []}}), "empty token"),
    "relative-node": (_with(ARCH_OK, topics={"/t": {"pubs": ["a"], "subs": []}}), "not global"),
    "server-null": (_with(ARCH_OK, services={"/s": [None]}), "not null"),
    "deep": ("[" * 100_000, "not JSON"),
}


@pytest.mark.parametrize("case", sorted(BAD_ARCH))
def test_bad_arch_records_raise_one_line_errors(case: str) -> None:
    text, expected = BAD_ARCH[case]
    with pytest.raises(RecordError) as raised:
        decode_arch(text)
    message = raised.value.message
    assert expected in message
    assert "\n" not in message
    assert str(raised.value) == message


BAD_CALLS = {
    "ok-string": (_with(CALL_OK, ok="yes"), "'ok' must be true or false"),
    "ok-without-response": (_with(CALL_OK, response=None), "an object when 'ok' is true"),
    "failed-with-response": (_with(CALL_OK, ok=False), "null when 'ok' is false"),
    "request-list": (_with(CALL_OK, request=[]), "'request' must be an object"),
    "stamp-string": (_with(CALL_OK, stamp="1"), "'stamp' must be a number"),
    "stamp-bool": (_with(CALL_OK, stamp=True), "'stamp' must be a number"),
    "delay-negative": (_with(CALL_OK, delay=-0.5), "must not be negative"),
    "service-relative": (_with(CALL_OK, service="s"), "not global"),
    "client-missing": (_with(CALL_OK, client=_DROP), "no 'client'"),
}


@pytest.mark.parametrize("case", sorted(BAD_CALLS))
def test_bad_call_records_raise(case: str) -> None:
    text, expected = BAD_CALLS[case]
    with pytest.raises(RecordError, match=re.escape(expected)):
        decode_call(text)


def test_non_finite_stamp_is_refused() -> None:
    text = encode(CALL).replace('"stamp":1379178103.5', '"stamp":NaN')
    with pytest.raises(RecordError, match="'stamp' must be finite"):
        decode_call(text)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ('{"version": 1, "params": []}', "'params' must be an object"),
        ('{"version": 1, "params": {"~private": 1}}', "private"),
        ('{"version": 1}', "no 'params'"),
    ],
)
def test_bad_param_records_raise(text: str, expected: str) -> None:
    with pytest.raises(RecordError, match=re.escape(expected)):
        decode_params(text)


def test_documented_examples_are_canonical_records() -> None:
    text = DOCS.read_text(encoding="utf-8")
    examples = re.findall(r"^```json\n(\{\".*\})\n```$", text, re.M)
    decoders: list[Decoder] = [decode_arch, decode_params, decode_call]
    assert len(examples) == len(decoders)
    for example, decode in zip(examples, decoders, strict=True):
        assert encode(decode(example)) == example


_names = st.builds(
    "/{}/{}".format, st.sampled_from(["a", "ns", "cf1"]), st.sampled_from(["x", "pose", "t_2"])
)


@settings(max_examples=60, deadline=None)
@given(
    st.dictionaries(_names, st.tuples(st.frozensets(_names), st.frozensets(_names)), max_size=5),
    st.dictionaries(_names, st.frozensets(_names), max_size=3),
)
def test_any_snapshot_round_trips(
    topics: dict[str, tuple[frozenset[str], frozenset[str]]], services: dict[str, frozenset[str]]
) -> None:
    snapshot = ArchSnapshot({t: TopicEnds(p, s) for t, (p, s) in topics.items()}, services)
    text = encode(snapshot)
    assert decode_arch(text) == snapshot
    assert encode(decode_arch(text)) == text
