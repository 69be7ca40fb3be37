"""Configurations mutated for fuzzing: what the fuzz tests of check and of the pipeline share."""

from __future__ import annotations

from hypothesis import strategies as st

SNIPPETS = [
    "/a/x",
    "a,b",
    "1",
    "-1",
    "(AB)*",
    "((A|B)+C)*",
    "a,c -> f",
    "{data: 3}",
    "pub,sub",
    "x == 1 and y < 2",
    "(",
    "->",
    "{a: [1, {b: }",
    "/a//b",
    "~p",
    "0.5",
    "",
    " ",
    "&amp;",
]


text_values = st.one_of(st.sampled_from(SNIPPETS), st.text(max_size=12))


def mutate(draw: st.DrawFn, source: bytes) -> bytes:
    """``source`` with 1 to 6 random edits: bytes deleted, inserted, duplicated or replaced
    by markup characters and invalid UTF-8."""
    data = bytearray(source)
    for _ in range(draw(st.integers(1, 6))):
        where = draw(st.integers(0, len(data)))
        kind = draw(st.sampled_from(["delete", "insert", "duplicate", "replace"]))
        span = draw(st.integers(1, 40))
        if kind == "delete":
            del data[where : where + span]
        elif kind == "insert":
            data[where:where] = draw(st.binary(min_size=1, max_size=span))
        elif kind == "duplicate":
            data[where:where] = data[where : where + span]
        else:
            data[where : where + 1] = draw(st.sampled_from([b"<", b">", b"&", b'"', b"\xff", b""]))
    return bytes(data)
