"""Condition value expressions: a small whitelisted grammar, parsed by hand and never ``eval``'d.

A ``<condition>``'s ``<value>`` is an expression such as ``pump_control==1`` or
``pose.position.z > 2.5 and not armed``::

    expr       := and_expr (('or' | '||') and_expr)*
    and_expr   := not_expr (('and' | '&&') not_expr)*
    not_expr   := ('not' | '!') not_expr | comparison
    comparison := additive (('==' | '!=' | '<' | '<=' | '>' | '>=') additive)?
    additive   := term (('+' | '-') term)*
    term       := unary (('*' | '/' | '%') unary)*
    unary      := '-' unary | primary
    primary    := NUMBER | STRING | 'true' | 'false' | 'True' | 'False'
                | FIELD | TOPIC | '(' expr ')'
    FIELD      := IDENT ('.' IDENT | '[' DIGITS ']')*

Numbers are decimal integers or floats (``2``, ``2.5``, ``.5``, ``1e-3``); strings are quoted
with ``'`` or ``"`` and take the escapes ``\\\\ \\' \\" \\n \\t \\r \\0 \\uXXXX``. A ``/`` where an
operand is expected starts a topic name (``/a/pump_control``), elsewhere it divides.
Comparisons do not chain (``a < b < c`` is an error: write ``a < b and b < c``). Parentheses
and prefix operators nest at most :data:`MAX_NESTING` deep and trees are at most
:data:`MAX_HEIGHT` high, so every function here stays far from Python's recursion limit.

The tree is canonical: ``and``/``or`` chains are flat (``a or (b or c)`` is one ``or`` of three
operands) and the alternative spellings ``&&``, ``||`` and ``!`` become ``and``, ``or`` and
``not``. The parser never builds a negative :class:`Number`: ``-3`` is ``Unary("-", 3)``.
"""

from __future__ import annotations

import re
import string
from collections.abc import Callable
from dataclasses import dataclass

from imrosc.schema.names import BAD_NAME, check_graph_name
from imrosc.schema.positions import OffsetError

__all__ = [
    "ARITHMETIC_OPS",
    "COMPARISON_OPS",
    "MAX_HEIGHT",
    "MAX_NESTING",
    "Binary",
    "Bool",
    "Expr",
    "ExpressionError",
    "Field",
    "Logical",
    "Number",
    "String",
    "Topic",
    "Unary",
    "fields",
    "parse_expression",
    "to_json",
]

MAX_NESTING = 64
"""The deepest nesting of parentheses and prefix operators an expression may have."""

MAX_HEIGHT = 128
"""The greatest height of an expression tree (a chain ``1+1+...`` adds one level per term)."""

ARITHMETIC_OPS = frozenset({"+", "-", "*", "/", "%"})
COMPARISON_OPS = frozenset({"==", "!=", "<", "<=", ">", ">="})
LOGICAL_OPS = frozenset({"and", "or"})
UNARY_OPS = frozenset({"-", "not"})

_IDENT_START = frozenset(string.ascii_letters + "_")
_IDENT_CHARS = frozenset(string.ascii_letters + string.digits + "_")
_DIGITS = frozenset(string.digits)
_TOPIC_CHARS = frozenset(string.ascii_letters + string.digits + "_/")
_SPACES = frozenset(" \t\r\n\f\v")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NUMBER = re.compile(r"(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_KEYWORDS = frozenset({"and", "or", "not", "true", "false", "True", "False"})
_MAX_INT_DIGITS = 4000
_ESCAPES = {"\\": "\\", "'": "'", '"': '"', "n": "\n", "t": "\t", "r": "\r", "0": "\0"}
_HEX = frozenset(string.hexdigits)


class ExpressionError(OffsetError):
    """An expression that cannot be parsed, converted or evaluated.

    ``message`` says what is wrong; ``offset`` is the 0-based index in the text (0 when there
    is no text, as in :func:`from_json` and :func:`evaluate`).
    """

    def __init__(self, message: str, offset: int = 0) -> None:
        super().__init__(message, offset)


@dataclass(frozen=True)
class Number:
    """An integer or float literal."""

    value: int | float


@dataclass(frozen=True)
class String:
    """A string literal."""

    value: str


@dataclass(frozen=True)
class Bool:
    """``true`` or ``false``."""

    value: bool


@dataclass(frozen=True)
class Field:
    """A field path of the message: names, and integer indexes into arrays."""

    path: tuple[str | int, ...]


@dataclass(frozen=True)
class Topic:
    """A global topic name used as an operand (the topic's latest value)."""

    name: str


@dataclass(frozen=True)
class Unary:
    """``-x`` or ``not x``."""

    op: str
    operand: Expr


@dataclass(frozen=True)
class Binary:
    """An arithmetic operation or a comparison."""

    op: str
    left: Expr
    right: Expr


@dataclass(frozen=True)
class Logical:
    """``and`` or ``or`` of two or more operands."""

    op: str
    operands: tuple[Expr, ...]


Expr = Number | String | Bool | Field | Topic | Unary | Binary | Logical


# --------------------------------------------------------------------------------------------
# Lexer


@dataclass(frozen=True)
class _Token:
    kind: str  # "number", "string", "bool", "name", "topic", "op" or "end"
    text: str  # canonical operator / name / topic; the decoded string for strings
    offset: int
    value: int | float | str | bool | None = None


_OPERATORS = (
    ("==", "=="),
    ("!=", "!="),
    ("<=", "<="),
    (">=", ">="),
    ("&&", "and"),
    ("||", "or"),
    ("<", "<"),
    (">", ">"),
    ("!", "not"),
    ("+", "+"),
    ("-", "-"),
    ("*", "*"),
    ("/", "/"),
    ("%", "%"),
    ("(", "("),
    (")", ")"),
    ("[", "["),
    ("]", "]"),
    (".", "."),
)


def _lex(text: str) -> list[_Token]:
    """Split the text into tokens; a ``/`` after an operand divides, elsewhere starts a topic."""
    tokens: list[_Token] = []
    index = 0
    length = len(text)
    operand_done = False  # the previous token ends an operand: an operator comes next
    while index < length:
        char = text[index]
        if char in _SPACES:
            index += 1
            continue
        start = index
        if char in _IDENT_START:
            match = _IDENT.match(text, index)
            assert match is not None
            word = match.group()
            index = match.end()
            if word in ("true", "True", "false", "False"):
                tokens.append(_Token("bool", word, start, word in ("true", "True")))
                operand_done = True
            elif word in ("and", "or", "not"):
                tokens.append(_Token("op", word, start))
                operand_done = False
            else:
                tokens.append(_Token("name", word, start))
                operand_done = True
            continue
        if char in _DIGITS or (char == "." and not operand_done and _digit_at(text, index + 1)):
            token, index = _lex_number(text, index)
            tokens.append(token)
            operand_done = True
            continue
        if char in ("'", '"'):
            value, index = _lex_string(text, index)
            tokens.append(_Token("string", value, start, value))
            operand_done = True
            continue
        if char == "/" and not operand_done:
            index += 1
            while index < length and text[index] in _TOPIC_CHARS:
                index += 1
            name = text[start:index]
            for problem in check_graph_name(name, "topic"):
                if problem.code == BAD_NAME:
                    raise ExpressionError(problem.message, start + problem.offset)
            tokens.append(_Token("topic", name, start))
            operand_done = True
            continue
        for spelling, canonical in _OPERATORS:
            if text.startswith(spelling, index):
                tokens.append(_Token("op", canonical, start))
                index += len(spelling)
                operand_done = canonical in (")", "]")
                break
        else:
            raise ExpressionError(_unexpected(text, index), index)
    tokens.append(_Token("end", "", length))
    return tokens


def _digit_at(text: str, index: int) -> bool:
    return index < len(text) and text[index] in _DIGITS


def _unexpected(text: str, index: int) -> str:
    char = text[index]
    if char == "=":
        return "unexpected '='; compare with '=='"
    if char == "&":
        return "unexpected '&'; write 'and' or '&&'"
    if char == "|":
        return "unexpected '|'; write 'or' or '||'"
    return f"unexpected character {char!r}"


def _lex_number(text: str, index: int) -> tuple[_Token, int]:
    """Read the number starting at ``index``; return its token and the index after it."""
    match = _NUMBER.match(text, index)
    assert match is not None
    end = match.end()
    if end < len(text) and (text[end] in _IDENT_CHARS or text[end] == "."):
        raise ExpressionError(f"invalid number {text[index : end + 1]!r}", index)
    literal = match.group()
    value: int | float
    if any(char in literal for char in ".eE"):
        value = float(literal)
    elif len(literal) > _MAX_INT_DIGITS:
        raise ExpressionError("integer literal is too long", index)
    else:
        value = int(literal)
    return _Token("number", literal, index, value), end


def _lex_string(text: str, index: int) -> tuple[str, int]:
    """Decode the string literal starting at ``index``; return it and the index after it."""
    quote = text[index]
    pieces: list[str] = []
    position = index + 1
    length = len(text)
    while position < length:
        char = text[position]
        if char == quote:
            return "".join(pieces), position + 1
        if char != "\\":
            pieces.append(char)
            position += 1
            continue
        if position + 1 >= length:
            break
        code = text[position + 1]
        if code in _ESCAPES:
            pieces.append(_ESCAPES[code])
            position += 2
        elif code == "u":
            digits = text[position + 2 : position + 6]
            if len(digits) != 4 or not all(digit in _HEX for digit in digits):
                raise ExpressionError("'\\u' needs four hexadecimal digits", position)
            pieces.append(chr(int(digits, 16)))
            position += 6
        else:
            raise ExpressionError(f"unknown escape '\\{code}' in string", position)
    raise ExpressionError("unterminated string", index)


# --------------------------------------------------------------------------------------------
# Parser


_OPERAND_KINDS = frozenset({"number", "string", "bool", "name", "topic"})


class _Parser:
    def __init__(self, text: str) -> None:
        self.tokens = _lex(text)
        self.index = 0
        self.nesting = 0

    def peek(self) -> _Token:
        return self.tokens[self.index]

    def take(self) -> _Token:
        token = self.tokens[self.index]
        if token.kind != "end":
            self.index += 1
        return token

    def at_op(self, *ops: str) -> bool:
        token = self.peek()
        return token.kind == "op" and token.text in ops

    def parse(self) -> Expr:
        if self.peek().kind == "end":
            raise ExpressionError("expression is empty", 0)
        result, _ = self.or_expr()
        token = self.peek()
        if token.kind != "end":
            if token.kind == "op" and token.text == ")":
                raise ExpressionError("unbalanced ')'", token.offset)
            if token.kind in _OPERAND_KINDS or (token.kind == "op" and token.text == "("):
                message = f"missing operator before {_describe(token)}"
                raise ExpressionError(message, token.offset)
            raise ExpressionError(f"unexpected {_describe(token)}", token.offset)
        return result

    def enter(self, offset: int) -> None:
        self.nesting += 1
        if self.nesting > MAX_NESTING:
            raise ExpressionError(f"expression is nested deeper than {MAX_NESTING} levels", offset)

    def or_expr(self) -> tuple[Expr, int]:
        return self.logical("or", self.and_expr)

    def and_expr(self) -> tuple[Expr, int]:
        return self.logical("and", self.not_expr)

    def logical(self, op: str, operand: Callable[[], tuple[Expr, int]]) -> tuple[Expr, int]:
        first, height = operand()
        if not self.at_op(op):
            return first, height
        operands = _flatten(op, first)
        offset = self.peek().offset
        while self.at_op(op):
            self.take()
            item, item_height = operand()
            operands.extend(_flatten(op, item))
            height = max(height, item_height)
        return Logical(op, tuple(operands)), _grow(height, offset)

    def not_expr(self) -> tuple[Expr, int]:
        if self.at_op("not"):
            token = self.take()
            self.enter(token.offset)
            operand, height = self.not_expr()
            self.nesting -= 1
            return Unary("not", operand), _grow(height, token.offset)
        return self.comparison()

    def comparison(self) -> tuple[Expr, int]:
        left, left_height = self.additive()
        if not self.at_op(*COMPARISON_OPS):
            return left, left_height
        op = self.take()
        right, right_height = self.additive()
        if self.at_op(*COMPARISON_OPS):
            raise ExpressionError(
                "comparisons cannot be chained; join them with 'and'", self.peek().offset
            )
        return Binary(op.text, left, right), _grow(max(left_height, right_height), op.offset)

    def binary(
        self, ops: tuple[str, ...], operand: Callable[[], tuple[Expr, int]]
    ) -> tuple[Expr, int]:
        left, height = operand()
        while self.at_op(*ops):
            op = self.take()
            right, right_height = operand()
            left, height = Binary(op.text, left, right), _grow(max(height, right_height), op.offset)
        return left, height

    def additive(self) -> tuple[Expr, int]:
        return self.binary(("+", "-"), self.term)

    def term(self) -> tuple[Expr, int]:
        return self.binary(("*", "/", "%"), self.unary)

    def unary(self) -> tuple[Expr, int]:
        if self.at_op("-"):
            token = self.take()
            self.enter(token.offset)
            operand, height = self.unary()
            self.nesting -= 1
            return Unary("-", operand), _grow(height, token.offset)
        return self.primary()

    def primary(self) -> tuple[Expr, int]:
        token = self.take()
        if token.kind == "number":
            assert isinstance(token.value, (int, float))
            return Number(token.value), 1
        if token.kind == "string":
            return String(token.text), 1
        if token.kind == "bool":
            return Bool(bool(token.value)), 1
        if token.kind == "topic":
            return Topic(token.text), 1
        if token.kind == "name":
            return self.field(token), 1
        if token.kind == "op" and token.text == "(":
            self.enter(token.offset)
            inner, height = self.or_expr()
            self.nesting -= 1
            if not self.at_op(")"):
                following = self.peek()
                if following.kind == "end":
                    raise ExpressionError("unbalanced '('", token.offset)
                raise ExpressionError(
                    f"expected ')' but found {_describe(following)}", following.offset
                )
            self.take()
            return inner, height
        if token.kind == "end":
            raise ExpressionError("expression ends where an operand is expected", token.offset)
        if token.kind == "op" and token.text == ")":
            raise ExpressionError("unexpected ')' where an operand is expected", token.offset)
        raise ExpressionError(f"expected an operand but found {_describe(token)}", token.offset)

    def field(self, first: _Token) -> Field:
        path: list[str | int] = [first.text]
        while True:
            if self.at_op("."):
                dot = self.take()
                name = self.take()
                if name.kind != "name":
                    raise ExpressionError("expected a field name after '.'", _after(dot, name))
                path.append(name.text)
            elif self.at_op("["):
                bracket = self.take()
                index = self.take()
                if index.kind != "number" or not isinstance(index.value, int):
                    raise ExpressionError(
                        "expected a non-negative integer index after '['", _after(bracket, index)
                    )
                if not self.at_op("]"):
                    raise ExpressionError("expected ']' after the index", self.peek().offset)
                self.take()
                path.append(index.value)
            else:
                return Field(tuple(path))


def _after(previous: _Token, token: _Token) -> int:
    return token.offset if token.kind != "end" else previous.offset + 1


def _describe(token: _Token) -> str:
    if token.kind == "end":
        return "the end"
    if token.kind == "string":
        return "a string"
    if token.kind == "number":
        return f"number {token.text}"
    if token.kind == "topic":
        return f"topic {token.text}"
    return f"'{token.text}'"


def _flatten(op: str, expr: Expr) -> list[Expr]:
    if isinstance(expr, Logical) and expr.op == op:
        return list(expr.operands)
    return [expr]


def _grow(height: int, offset: int) -> int:
    if height + 1 > MAX_HEIGHT:
        raise ExpressionError(f"expression is nested deeper than {MAX_HEIGHT} levels", offset)
    return height + 1


def parse_expression(text: str) -> Expr:
    """Parse an expression; raise :class:`ExpressionError` with an offset into ``text``."""
    return _Parser(text).parse()


# --------------------------------------------------------------------------------------------
# Queries and conversions


def fields(expr: Expr) -> frozenset[tuple[str | int, ...]]:
    """The field paths an expression reads."""
    if isinstance(expr, Field):
        return frozenset((expr.path,))
    if isinstance(expr, Unary):
        return fields(expr.operand)
    if isinstance(expr, Binary):
        return fields(expr.left) | fields(expr.right)
    if isinstance(expr, Logical):
        result: frozenset[tuple[str | int, ...]] = frozenset()
        for operand in expr.operands:
            result |= fields(operand)
        return result
    return frozenset()


def to_json(expr: Expr) -> dict[str, object]:
    """A JSON-ready form of the expression (plain dicts, lists, strings, numbers and bools).

    Literals are ``{"value": 3}``, ``{"value": "s"}``, ``{"value": true}``; field paths
    ``{"field": ["ranges", 0]}``; topics ``{"topic": "/a/b"}``; operations
    ``{"op": "==", "args": [...]}`` (one argument for ``-``/``not``, two for arithmetic and
    comparisons, two or more for ``and``/``or``).
    """
    if isinstance(expr, (Number, String, Bool)):
        return {"value": expr.value}
    if isinstance(expr, Field):
        return {"field": list(expr.path)}
    if isinstance(expr, Topic):
        return {"topic": expr.name}
    if isinstance(expr, Unary):
        return {"op": expr.op, "args": [to_json(expr.operand)]}
    if isinstance(expr, Binary):
        return {"op": expr.op, "args": [to_json(expr.left), to_json(expr.right)]}
    return {"op": expr.op, "args": [to_json(operand) for operand in expr.operands]}
