"""The one record encoder (``imrosc/onboard/records.py``) writes exactly the records
``imrosc.records`` reads: every text decodes, and is the very text ``records.encode`` writes
for the decoded record."""

from __future__ import annotations

import string
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc import records
from imrosc.onboard import records as encoder

TOKEN = st.builds(
    str.__add__,
    st.sampled_from(string.ascii_letters),
    st.text(string.ascii_letters + string.digits + "_", max_size=5),
)
NAME = st.lists(TOKEN, min_size=1, max_size=3).map(lambda parts: "/" + "/".join(parts))
NODES = st.sets(NAME, max_size=4)
SCALAR = st.none() | st.booleans() | st.integers(-(2**40), 2**40) | st.floats() | st.text()
JSON = st.recursive(
    SCALAR,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(TOKEN, inner, max_size=3),
    max_leaves=8,
)


@settings(max_examples=100, deadline=None)
@given(st.dictionaries(NAME, st.tuples(NODES, NODES)), st.dictionaries(NAME, NODES))
def test_architecture_text_is_canonical_and_decodes(
    topics: dict[str, tuple[set[str], set[str]]], services: dict[str, set[str]]
) -> None:
    text = encoder.arch_text(topics, services)
    decoded = records.decode_arch(text)
    expected = records.ArchSnapshot(
        {t: records.TopicEnds(frozenset(p), frozenset(s)) for t, (p, s) in topics.items()},
        {name: frozenset(servers) for name, servers in services.items()},
    )
    assert decoded == expected
    assert text == records.encode(expected)


@settings(max_examples=100, deadline=None)
@given(st.dictionaries(NAME, JSON, max_size=5))
def test_parameter_text_is_canonical_and_decodes(params: dict[str, Any]) -> None:
    text = encoder.params_text(params)
    decoded = records.decode_params(text)
    assert set(decoded.params) == set(params)
    assert text == records.encode(decoded)
    assert text == records.encode(records.ParamSnapshot(params))


@settings(max_examples=100, deadline=None)
@given(
    NAME,
    NAME,
    NAME,
    st.dictionaries(TOKEN, JSON, max_size=4),
    st.none() | st.dictionaries(TOKEN, JSON, max_size=4),
    st.floats(0, 2e9),
    st.floats(-1.0, 10.0),
)
def test_call_text_is_canonical_and_decodes(
    service: str,
    client: str,
    server: str,
    request: dict[str, Any],
    response: dict[str, Any] | None,
    stamp: float,
    delay: float,
) -> None:
    text = encoder.call_text(service, client, server, request, response, stamp, delay)
    call = records.decode_call(text)
    assert (call.service, call.client, call.server) == (service, client, server)
    assert call.ok is (response is not None)
    assert call.stamp == stamp
    assert call.delay == max(0.0, delay)
    assert text == records.encode(call)


def test_a_failed_call_has_no_response() -> None:
    text = encoder.call_text("/s", "/c", "/n", {"k": 0}, None, 10.0, 0.002)
    call = records.decode_call(text)
    assert not call.ok
    assert call.response is None
    assert call.request == {"k": 0}
