"""Plain YAML, safely and with positions: one pass from parser events to a small tree.

The graph file needs mappings, lists and scalars, nothing more. :func:`compose_plain` reads
ruamel.yaml's event stream once and builds the tree itself, so it can refuse what a graph file
never needs before it could do harm: anchors and aliases (nothing is ever expanded, so a
"billion laughs" costs no more than its text), tags (no constructor ever runs), several
documents, and nesting deeper than a limit (no recursion anywhere). Every value keeps the
1-based line and column where it starts. Plain scalars are resolved as YAML 1.2 does
(``1`` is an integer, ``null`` and the empty value are null, ``yes`` is a string).

>>> tree, problems = compose_plain("a: [1, 'x']\\n")
>>> problems, tree.pairs[0][1].items[1]
([], YScalar(value='x', tag='str', quoted=True, line=1, column=8))
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ruamel.yaml import YAML
from ruamel.yaml.error import MarkedYAMLError, YAMLError
from ruamel.yaml.events import (
    AliasEvent,
    CollectionEndEvent,
    CollectionStartEvent,
    DocumentStartEvent,
    Event,
    MappingStartEvent,
    NodeEvent,
    ScalarEvent,
)
from ruamel.yaml.nodes import ScalarNode
from ruamel.yaml.reader import ReaderError

__all__ = ["YList", "YMap", "YProblem", "YScalar", "YValue", "compose_plain"]

_CORE = "tag:yaml.org,2002:"
_PLAIN_ONLY = "plain YAML only: no anchors, aliases or tags"


@dataclass(frozen=True)
class YScalar:
    """A scalar: its text, its resolved core tag (``str``, ``int``, ``null``, ...), where."""

    value: str
    tag: str
    quoted: bool
    line: int
    column: int


@dataclass
class YList:
    """A sequence and where it starts."""

    line: int
    column: int
    items: list[YValue] = field(default_factory=list)


@dataclass
class YMap:
    """A mapping (pairs in file order, repeats kept) and where it starts."""

    line: int
    column: int
    pairs: list[tuple[YValue, YValue]] = field(default_factory=list)


YValue = YScalar | YList | YMap


@dataclass(frozen=True)
class YProblem:
    """Why the text is refused: a syntax error, or a construct plain YAML does not allow."""

    line: int
    column: int
    message: str
    syntax: bool


def _at(event: Event) -> tuple[int, int]:
    mark = event.start_mark
    return mark.line + 1, mark.column + 1


def _syntax(text: str, error: YAMLError) -> YProblem:
    """The problem of a YAML error, at its place."""
    line, column, message = 1, 1, str(error).split("\n")[0]
    if isinstance(error, MarkedYAMLError):
        mark = error.problem_mark or error.context_mark
        if mark is not None:
            line, column = mark.line + 1, mark.column + 1
        message = str(error.problem or error.context or message)
    elif isinstance(error, ReaderError) and isinstance(error.position, int):
        before = text[: error.position]
        line = before.count("\n") + 1
        column = error.position - (before.rfind("\n") + 1) + 1
    return YProblem(line, column, f"invalid YAML: {message}", syntax=True)


@dataclass
class _Composer:
    """The state of one pass: the open collections, the refusals, the result."""

    max_depth: int
    yaml: YAML = field(default_factory=lambda: YAML(typ="safe", pure=True))
    stack: list[tuple[YList | YMap, list[YValue]]] = field(default_factory=list)
    problems: list[YProblem] = field(default_factory=list)
    aliases: set[str] = field(default_factory=set)
    root: YValue | None = None
    documents: int = 0

    def refuse(self, event: Event, message: str) -> None:
        self.problems.append(YProblem(*_at(event), message, syntax=False))

    def add(self, value: YValue) -> None:
        """Put a finished value into the open collection (or make it the root)."""
        if not self.stack:
            self.root = value
            return
        parent, pending = self.stack[-1]
        if isinstance(parent, YList):
            parent.items.append(value)
        elif pending:
            parent.pairs.append((pending.pop(), value))
        else:
            pending.append(value)

    def scalar(self, event: ScalarEvent) -> YScalar:
        tag = "str"
        if event.style is None and event.implicit[0]:
            resolved = self.yaml.resolver.resolve(ScalarNode, event.value, (True, False))
            tag = str(resolved).removeprefix(_CORE)
        quoted = event.style in ("'", '"')
        return YScalar(str(event.value), tag, quoted, *_at(event))

    def screen(self, event: Event) -> bool:
        """Refuse an anchor, alias or tag; False when the event must not be used."""
        if isinstance(event, AliasEvent):
            anchor = str(event.anchor)
            if anchor not in self.aliases:  # each alias once: a billion laughs has many
                self.aliases.add(anchor)
                self.refuse(event, f"alias *{anchor} is not allowed: {_PLAIN_ONLY}")
            return False
        usable = True
        if isinstance(event, NodeEvent) and event.anchor is not None:
            self.refuse(event, f"anchor &{event.anchor} is not allowed: {_PLAIN_ONLY}")
            usable = False
        if isinstance(event, (ScalarEvent, CollectionStartEvent)) and event.tag is not None:
            tag = str(event.tag).replace(_CORE, "!!")
            self.refuse(event, f"tag {tag} is not allowed: {_PLAIN_ONLY}")
            usable = False
        return usable

    def feed(self, event: Event) -> bool:
        """Take one event; False to stop reading (the rest cannot be trusted)."""
        if isinstance(event, DocumentStartEvent):
            self.documents += 1
            if self.documents > 1:
                self.refuse(event, "expected one YAML document, found several")
                return False
        self.screen(event)
        if isinstance(event, (ScalarEvent, AliasEvent)):
            value = self.scalar(event) if isinstance(event, ScalarEvent) else None
            self.add(value or YScalar("", "null", False, *_at(event)))
        elif isinstance(event, CollectionStartEvent):
            if len(self.stack) >= self.max_depth:
                self.refuse(event, f"collections are nested deeper than {self.max_depth} levels")
                return False
            line, column = _at(event)
            opened = (
                YMap(line, column) if isinstance(event, MappingStartEvent) else YList(line, column)
            )
            self.stack.append((opened, []))
        elif isinstance(event, CollectionEndEvent):
            closed, _ = self.stack.pop()
            self.add(closed)
        return True


def compose_plain(text: str, *, max_depth: int = 32) -> tuple[YValue | None, list[YProblem]]:
    """The tree of a one-document plain YAML text; None and the problems if refused.

    An empty document (no content, or only comments) gives no tree and no problem.
    """
    composer = _Composer(max_depth)
    try:
        for event in composer.yaml.parse(text):
            if not composer.feed(event):
                break
    except YAMLError as error:
        return None, [*composer.problems, _syntax(text, error)]
    if composer.problems:
        return None, composer.problems
    return composer.root, []
