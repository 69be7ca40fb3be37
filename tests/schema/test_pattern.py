"""Tests for temporal patterns (thesis section 3.4.4.2)."""

from __future__ import annotations

import string

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imrosc.schema.pattern import (
    MAX_NESTING,
    Concat,
    Epsilon,
    Pattern,
    PatternError,
    Plus,
    Star,
    Symbol,
    Union,
    event_letters,
    parse_pattern,
    placeholders,
    substitute,
    to_text,
)

A, B, C = Symbol("A"), Symbol("B"), Symbol("C")
a, b, c = Symbol("a"), Symbol("b"), Symbol("c")


@pytest.mark.parametrize(
    ("text", "tree"),
    [
        ("(AB)*", Star(Concat((A, B)))),
        ("(AAB)*", Star(Concat((A, A, B)))),
        ("((A|B)+C)*", Star(Concat((Plus(Union((A, B))), C)))),
        ("a", a),
        ("-", Epsilon()),
        ("ab*|c", Union((Concat((a, Star(b))), c))),
        ("a|b|c", Union((a, b, c))),
        ("a|(b|c)", Union((a, b, c))),
        ("(ab)c", Concat((a, b, c))),
        ("a(bc)", Concat((a, b, c))),
        ("(a|b)(c|A)", Concat((Union((a, b)), Union((c, A))))),
        ("((a))", a),
        (" ( A B ) * ", Star(Concat((A, B)))),
        ("a\tb\nc", Concat((a, b, c))),
        ("a-b", Concat((a, Epsilon(), b))),
        ("(a|-)b", Concat((Union((a, Epsilon())), b))),
        ("a**", Star(a)),
        ("a+*", Star(a)),
        ("a*+", Star(a)),
        ("a++", Plus(a)),
        ("(a*)*", Star(a)),
        ("(-)*", Star(Epsilon())),
    ],
)
def test_parse_known_answers(text: str, tree: Pattern) -> None:
    assert parse_pattern(text) == tree


@pytest.mark.parametrize(
    ("text", "canonical"),
    [
        ("(AB)*", "(AB)*"),
        ("(AAB)*", "(AAB)*"),
        ("((A|B)+C)*", "((A|B)+C)*"),
        ("((a)(b))", "ab"),
        ("(a|b)|c", "a|b|c"),
        ("(ab)|(cd)", "ab|cd"),
        ("((ab)*)+", "(ab)*"),
        ("a ( b | c ) *", "a(b|c)*"),
        ("(a|-)", "a|-"),
    ],
)
def test_to_text_uses_fewest_parentheses(text: str, canonical: str) -> None:
    assert to_text(parse_pattern(text)) == canonical


@pytest.mark.parametrize(
    ("text", "offset", "message"),
    [
        ("", 0, "pattern is empty"),
        ("   ", 0, "pattern is empty"),
        ("()", 0, "empty group '()'"),
        ("a( )", 1, "empty group '()'"),
        ("a|", 1, "'|' has nothing after it"),
        ("|a", 0, "'|' has nothing before it"),
        ("a||b", 2, "'|' has nothing before it"),
        ("(|a)", 1, "'|' has nothing before it"),
        ("(a|)", 2, "'|' has nothing after it"),
        ("*a", 0, "'*' has nothing before it to repeat"),
        ("a|+", 2, "'+' has nothing before it to repeat"),
        ("(*)", 1, "'*' has nothing before it to repeat"),
        ("(a", 0, "unbalanced '('"),
        ("(", 0, "unbalanced '('"),
        ("a)", 1, "unbalanced ')'"),
        (")", 0, "unbalanced ')'"),
        ("(a))", 3, "unbalanced ')'"),
        ("a1", 1, "unexpected character '1'"),
        ("a.b", 1, "unexpected character '.'"),
        ("aé", 1, "unexpected character 'é'"),
        ("a?", 1, "unexpected character '?'"),
    ],
)
def test_errors_have_messages_and_offsets(text: str, offset: int, message: str) -> None:
    with pytest.raises(PatternError) as caught:
        parse_pattern(text)
    assert caught.value.offset == offset
    assert caught.value.message.startswith(message)
    assert message in str(caught.value)


def test_nesting_is_limited() -> None:
    ok = "(" * MAX_NESTING + "a" + ")" * MAX_NESTING
    assert parse_pattern(ok) == a
    deep = "(" * (MAX_NESTING + 1) + "a" + ")" * (MAX_NESTING + 1)
    with pytest.raises(PatternError) as caught:
        parse_pattern(deep)
    assert caught.value.offset == MAX_NESTING
    assert "nested" in caught.value.message


def test_long_patterns_stay_flat() -> None:
    text = "ab" * 5000 + "*" * 5000
    tree = parse_pattern(text)
    assert isinstance(tree, Concat)
    assert tree.parts[-1] == Star(b)
    assert to_text(tree) == "ab" * 5000 + "*"


def test_placeholders_and_event_letters() -> None:
    tree = parse_pattern("((A|b)+C)*a-")
    assert placeholders(tree) == frozenset({"A", "C"})
    assert event_letters(tree) == frozenset({"a", "b"})
    assert placeholders(parse_pattern("-")) == frozenset()


def test_substitute_binds_placeholders() -> None:
    tree = parse_pattern("(AB)*")
    assert substitute(tree, {"A": "a", "B": "c"}) == parse_pattern("(ac)*")
    assert to_text(substitute(parse_pattern("((A|B)+C)*"), {"A": "x", "B": "y", "C": "z"})) == (
        "((x|y)+z)*"
    )
    # Event letters and unmapped placeholders stay.
    assert substitute(parse_pattern("aB|C"), {"a": "q", "B": "b"}) == parse_pattern("ab|C")


def test_to_text_of_unparsed_trees() -> None:
    assert to_text(Concat(())) == "-"
    assert to_text(Concat((a,))) == "a"
    assert to_text(Union((Concat((a, b)),))) == "ab"
    assert to_text(Concat((Concat((a, b)), c))) == "(ab)c"
    assert to_text(Union((Union((a, b)), c))) == "(a|b)|c"
    assert to_text(Star(Star(a))) == "a**"
    with pytest.raises(PatternError):
        to_text(Union(()))


# -- properties --------------------------------------------------------------------------------


def _concat(parts: list[Pattern]) -> Pattern:
    flat: list[Pattern] = []
    for part in parts:
        flat.extend(part.parts if isinstance(part, Concat) else (part,))
    return Concat(tuple(flat))


def _union(options: list[Pattern]) -> Pattern:
    flat: list[Pattern] = []
    for option in options:
        flat.extend(option.options if isinstance(option, Union) else (option,))
    return Union(tuple(flat))


def _star(inner: Pattern) -> Pattern:
    return Star(inner.inner if isinstance(inner, (Star, Plus)) else inner)


def _plus(inner: Pattern) -> Pattern:
    if isinstance(inner, Star):
        return inner
    return inner if isinstance(inner, Plus) else Plus(inner)


_leaves: st.SearchStrategy[Pattern] = st.one_of(
    st.sampled_from(string.ascii_letters).map(Symbol), st.just(Epsilon())
)
patterns: st.SearchStrategy[Pattern] = st.recursive(
    _leaves,
    lambda children: st.one_of(
        st.lists(children, min_size=2, max_size=4).map(_concat),
        st.lists(children, min_size=2, max_size=4).map(_union),
        children.map(_star),
        children.map(_plus),
    ),
    max_leaves=20,
)

_pattern_chars = st.text(st.sampled_from("aAbZ|*+()- \t1.é"), max_size=30)


@settings(deadline=None)
@given(st.one_of(st.text(), _pattern_chars))
def test_parse_never_raises_anything_else(text: str) -> None:
    try:
        tree = parse_pattern(text)
    except PatternError as error:
        assert 0 <= error.offset <= len(text)
        assert error.message
    else:
        assert parse_pattern(to_text(tree)) == tree


@settings(deadline=None)
@given(patterns)
def test_generated_patterns_round_trip(tree: Pattern) -> None:
    text = to_text(tree)
    assert parse_pattern(text) == tree
    assert to_text(parse_pattern(text)) == text


@settings(deadline=None)
@given(patterns)
def test_letters_partition(tree: Pattern) -> None:
    holes, events = placeholders(tree), event_letters(tree)
    assert holes.isdisjoint(events)
    assert all(letter.isupper() for letter in holes)
    assert all(letter.islower() for letter in events)
    bound = substitute(tree, {hole: "e" for hole in holes})
    assert placeholders(bound) == frozenset()
    assert event_letters(bound) == events | ({"e"} if holes else set())
