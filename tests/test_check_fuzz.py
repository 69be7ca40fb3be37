"""Generated and mutated XML never makes the checker raise: it only reports diagnostics."""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imrosc.check import check_bytes
from imrosc.codes import BY_NAME
from tests.fuzz_support import mutate, text_values

EXAMPLES = [
    p.read_bytes() for p in sorted((Path(__file__).parent.parent / "examples").glob("*.xml"))
]

TAGS = [
    *("imROS", "scope", "publish", "topic", "call", "service", "param", "arch", "temporal"),
    *("pattern", "condition", "value", "detect", "bag", "check", "success", "fail"),
    *("monitor", "block", "action", "violation", "junk"),
]
ATTRIBUTES = [
    *("project", "id", "label", "relative", "conds", "events", "inv", "launch", "launch_ros2"),
    *("threshold", "beta", "window", "confidence", "drop_ratio", "hull_chunk"),
    *("discrete", "budget", "max_interval", "max_events", "period", "bogus"),
    *("alarm_persist", "alarm_seconds", "alarm_distinct", "alarm_window", "alarm_severe"),
]


@st.composite
def elements(draw: st.DrawFn, depth: int = 0) -> str:
    tag = draw(st.sampled_from(TAGS))
    attributes = draw(st.dictionaries(st.sampled_from(ATTRIBUTES), text_values, max_size=3))
    rendered = "".join(f" {name}={quoteattr(value)}" for name, value in attributes.items())
    inner = escape(draw(text_values))
    if depth < 3:
        inner += "".join(draw(st.lists(elements(depth + 1), max_size=4)))
    return f"<{tag}{rendered}>{inner}</{tag}>"


@st.composite
def documents(draw: st.DrawFn) -> bytes:
    body = "".join(draw(st.lists(elements(1), max_size=5)))
    root = draw(st.sampled_from(["imROS", "imROS", "config"]))
    return f'<{root} project="p">{body}</{root}>'.encode()


@st.composite
def mutated_examples(draw: st.DrawFn) -> bytes:
    return mutate(draw, draw(st.sampled_from(EXAMPLES)))


def assert_only_diagnostics(data: bytes) -> None:
    for diagnostic in check_bytes(data, "fuzz.xml"):
        assert diagnostic.code in BY_NAME
        assert diagnostic.line >= 1 and diagnostic.column >= 1


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(documents())
def test_generated_documents_never_raise(data: bytes) -> None:
    assert_only_diagnostics(data)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_examples())
def test_mutated_examples_never_raise(data: bytes) -> None:
    assert_only_diagnostics(data)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200))
def test_arbitrary_bytes_never_raise(data: bytes) -> None:
    assert_only_diagnostics(data)
