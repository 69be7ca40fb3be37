"""Semantic checks the XSD cannot express, as one pass over a loaded configuration.

It resolves ids (scope elements and actions: lowercase letters; conditions: digits), checks
the mini-languages (id lists, ``POINTS -> ACTIONS``, patterns, condition expressions, action
values), ROS names, and combinations that cannot work. It is defensive: it runs even on a
tree with structural errors and never raises.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from lxml import etree

from imrosc.diagnostics import Diagnostic, make
from imrosc.runtime.families import PUBLISH, select
from imrosc.schema.expression import (
    Binary,
    Expr,
    ExpressionError,
    Logical,
    Topic,
    Unary,
    fields,
    parse_expression,
)
from imrosc.schema.flowmap import FlowMapError, parse_flow_mapping
from imrosc.schema.loader import LoadedConfig
from imrosc.schema.names import check_graph_name
from imrosc.schema.pattern import PatternError, event_letters, parse_pattern, placeholders

FAMILY_SEPARATORS = ", \t\r\n"
"""What separates the names of a ``families`` attribute."""
POINT_TAGS = ("publish", "call", "param", "arch", "temporal")
"""Scope elements that are program points (a scope-level ``param`` needs an id to be named)."""

EVENT_TAGS = ("publish", "call")
"""Points whose messages are events of a ``temporal`` (thesis 3.4.4)."""

ARCH_KINDS = ("pub", "sub", "srv")

ONSET_ATTRIBUTES = ("onset", "onset_topic", "onsets")
"""The ways a ``<fail>`` gives its fault's onset (at most one)."""

_LETTER_ID = re.compile(r"[a-z]+")
_DIGIT_ID = re.compile(r"[0-9]+")
_VIOLATION = re.compile(r"^(?P<points>[^>-]*)->(?P<actions>.*)$", re.DOTALL)


@dataclass(frozen=True)
class Token:
    """A stripped piece of a list and its offset in the original string."""

    text: str
    offset: int


def split_tokens(value: str, separators: str = ",") -> list[Token]:
    """Split ``value`` on any of ``separators`` (and strip), keeping offsets.

    >>> [(t.text, t.offset) for t in split_tokens(" a, b ,c")]
    [('a', 1), ('b', 4), ('c', 7)]
    """
    pattern = "[^" + re.escape(separators) + "]+" if separators else ".+"
    tokens = []
    for piece in re.finditer(pattern, value):
        stripped = piece.group().strip()
        if stripped:
            tokens.append(Token(stripped, piece.start() + piece.group().index(stripped)))
        else:
            tokens.append(Token("", piece.start()))
    return tokens


def element_text(element: etree._Element) -> Token:
    """The element's leading text, stripped, with the offset where it starts."""
    raw = element.text or ""
    stripped = raw.strip()
    return Token(stripped, raw.index(stripped) if stripped else 0)


def children(element: etree._Element, tag: str) -> list[etree._Element]:
    """Direct element children called ``tag``."""
    return [child for child in element if child.tag == tag]


@dataclass
class _Pass:
    config: LoadedConfig
    found: list[Diagnostic] = field(default_factory=list)
    ids: dict[str, etree._Element] = field(default_factory=dict)
    conditions: dict[str, etree._Element] = field(default_factory=dict)
    used_conditions: set[str] = field(default_factory=set)
    used_actions: set[str] = field(default_factory=set)

    # -- reporting -----------------------------------------------------------------------

    def at_element(self, element: etree._Element, code: str, message: str) -> None:
        line, column = self.config.element_position(element)
        self.found.append(make(self.config.path, line, column, code, message))

    def at_attribute(
        self, element: etree._Element, name: str, code: str, message: str, offset: int = 0
    ) -> None:
        line, column = self.config.attribute_position(element, name, relative=offset)
        self.found.append(make(self.config.path, line, column, code, message))

    def at_text(self, element: etree._Element, code: str, message: str, offset: int = 0) -> None:
        line, column = self.config.text_position(element, offset)
        self.found.append(make(self.config.path, line, column, code, message))

    # -- the pass --------------------------------------------------------------------------

    def run(self) -> list[Diagnostic]:
        root = self.config.root
        scopes = children(root, "scope")
        monitors = children(root, "monitor")
        self.collect_ids(scopes, monitors)
        for scope in scopes:
            for element in scope:
                self.check_scope_element(element)
        for check in children(root, "check"):
            self.check_check(check)
        for detect in children(root, "detect"):
            self.check_detect(detect)
        for monitor in monitors:
            self.check_monitor(monitor, root)
        self.report_unused()
        return self.found

    def collect_ids(self, scopes: list[etree._Element], monitors: list[etree._Element]) -> None:
        named = [e for scope in scopes for e in scope if e.tag in POINT_TAGS]
        named += [a for monitor in monitors for a in children(monitor, "action")]
        for element in named:
            ident = element.get("id")
            if ident is None:
                continue
            if not _LETTER_ID.fullmatch(ident):
                what = "action" if element.tag == "action" else f"<{element.tag}>"
                message = f"id '{ident}' of {what} must be lowercase letters (e.g. 'a')"
                self.at_attribute(element, "id", "bad-id", message)
            self.remember(self.ids, element, "id", ident)
        for scope in scopes:
            for condition in children(scope, "condition"):
                self.collect_condition_id(condition)

    def collect_condition_id(self, condition: etree._Element) -> None:
        ident, label = condition.get("id"), condition.get("label")
        if ident is not None and label is not None:
            message = "<condition> takes 'id' or its alias 'label', not both"
            self.at_attribute(condition, "label", "bad-id", message)
        if ident is None and label is None:
            self.at_element(condition, "missing-attribute", "<condition> needs attribute 'id'")
            return
        attribute = "id" if ident is not None else "label"
        value = condition.get(attribute, "")
        if not _DIGIT_ID.fullmatch(value):
            message = f"condition {attribute} '{value}' must be digits (e.g. '1')"
            self.at_attribute(condition, attribute, "bad-id", message)
        self.remember(self.conditions, condition, attribute, value)

    def remember(
        self, table: dict[str, etree._Element], element: etree._Element, attribute: str, key: str
    ) -> None:
        if key in table:
            line, _ = self.config.element_position(table[key])
            message = f"id '{key}' is already used by <{table[key].tag}> on line {line}"
            self.at_attribute(element, attribute, "duplicate-id", message)
        else:
            table[key] = element

    def check_scope_element(self, element: etree._Element) -> None:
        if element.tag == "publish":
            self.check_point_name(element, "topic")
            self.check_relative(element)
            self.check_families(element)
        elif element.tag == "call":
            self.check_point_name(element, "service")
        elif element.tag == "param":
            self.check_name(element, "parameter")
        elif element.tag == "arch":
            self.check_arch(element)
        elif element.tag == "temporal":
            self.check_temporal(element)
        elif element.tag == "condition":
            self.check_condition(element)
        for param in children(element, "param") if element.tag in EVENT_TAGS else []:
            self.check_name(param, "parameter")
        if element.tag in POINT_TAGS:
            self.check_conds(element)

    def check_name(self, element: etree._Element, kind: str, token: Token | None = None) -> None:
        """Check the ROS name held in the element's text (or the given token of it)."""
        token = token or element_text(element)
        if not token.text:
            self.at_element(element, "missing-topic", f"<{element.tag}> names no {kind}")
            return
        for problem in check_graph_name(token.text, kind):
            self.at_text(element, problem.code, problem.message, token.offset + problem.offset)

    def check_point_name(self, element: etree._Element, child_tag: str) -> None:
        text = element_text(element)
        tails = [c.tail for c in element if c.tail and c.tail.strip()]
        named = children(element, child_tag)
        if (text.text or tails) and named:
            message = (
                f"<{element.tag}> gives its {child_tag} both as text and as <{child_tag}>; "
                f"use one form"
            )
            self.at_element(element, "topic-conflict", message)
        elif tails:
            message = f"<{element.tag}> has text after a child element; put the {child_tag} first"
            self.at_element(element, "topic-conflict", message)
        elif text.text:
            self.check_name(element, child_tag, text)
        elif not named:
            self.at_element(element, "missing-topic", f"<{element.tag}> names no {child_tag}")
        for child in named:
            self.check_name(child, child_tag)
        if element.tag == "call" and len(named) > 1:
            message = "<call> monitors one service; give one <service>"
            self.at_element(named[1], "topic-conflict", message)

    def check_relative(self, element: etree._Element) -> None:
        value = element.get("relative")
        if value is None:
            return
        try:
            hops = int(value.strip())
        except ValueError:
            return  # the schema reports a non-integer
        if hops < 0:
            message = f"relative={hops}: the number of publisher hops must be 0 or more"
            self.at_attribute(element, "relative", "bad-relative", message)

    def check_families(self, element: etree._Element) -> None:
        value = element.get("families")
        if value is None:
            return
        tokens = [t for t in split_tokens(value, FAMILY_SEPARATORS) if t.text]
        if not tokens:
            message = "families names no family: leave the attribute out for all of them"
            self.at_attribute(element, "families", "unknown-family", message)
            return
        _, unknown = select([t.text for t in tokens], PUBLISH)
        for token in tokens:
            if token.text in unknown:
                message = (
                    f"{token.text!r} is no invariant family or group of a publish point "
                    f"(groups: default, time-related, polygon)"
                )
                self.at_attribute(element, "families", "unknown-family", message, token.offset)

    def check_conds(self, element: etree._Element) -> None:
        value = element.get("conds")
        if value is None:
            return
        for token in split_tokens(value):
            if not token.text:
                self.at_attribute(element, "conds", "bad-id", "empty id in conds", token.offset)
            elif token.text in self.conditions:
                self.used_conditions.add(token.text)
            elif token.text in self.ids:
                other = self.ids[token.text].tag
                message = f"conds names '{token.text}', which is a <{other}>, not a <condition>"
                self.at_attribute(element, "conds", "wrong-ref-kind", message, token.offset)
            else:
                message = f"conds names '{token.text}', but no <condition> has that id"
                self.at_attribute(element, "conds", "unknown-ref", message, token.offset)

    def check_arch(self, element: etree._Element) -> None:
        text = element.text or ""
        for token in split_tokens(text):
            if token.text not in ARCH_KINDS:
                shown = token.text or "an empty kind"
                message = f"{shown!r} is not an architecture kind; use pub, sub or srv"
                self.at_text(element, "bad-arch-kind", message, token.offset)

    def resolve(
        self, element: etree._Element, attribute: str, token: Token, kinds: tuple[str, ...]
    ) -> bool:
        """Check that the id token names an element of one of ``kinds``."""
        what = " or ".join(f"<{k}>" for k in kinds)
        if not token.text:
            message = f"empty id in {attribute}"
            self.at_attribute(element, attribute, "bad-id", message, token.offset)
            return False
        target = self.ids.get(token.text)
        if target is None:
            message = f"{attribute} names '{token.text}', but no {what} has that id"
            self.at_attribute(element, attribute, "unknown-ref", message, token.offset)
            return False
        if target.tag not in kinds:
            message = f"{attribute} names '{token.text}', a <{target.tag}>; expected {what}"
            self.at_attribute(element, attribute, "wrong-ref-kind", message, token.offset)
            return False
        return True

    def check_temporal(self, element: etree._Element) -> None:
        events = [
            token.text
            for token in split_tokens(element.get("events", ""))
            if self.resolve(element, "events", token, EVENT_TAGS)
        ]
        distinct = sorted(set(events))
        involved: set[str] = set(distinct) if len(distinct) >= 2 else set()
        for pattern in children(element, "pattern"):
            involved |= self.check_pattern(pattern, distinct)
        for event in distinct:
            if event not in involved:
                message = (
                    f"event '{event}' is the only event of <temporal id="
                    f'"{element.get("id")}"> and no pattern names it: nothing can involve it'
                )
                self.at_attribute(element, "events", "uninvolved-event", message)

    def check_pattern(self, pattern: etree._Element, events: list[str]) -> set[str]:
        """Check one pattern; return the events it can involve."""
        token = element_text(pattern)
        try:
            tree = parse_pattern(pattern.text or "")
        except PatternError as error:
            self.at_text(pattern, "bad-pattern", f"pattern: {error.message}", error.offset)
            return set()
        raw = pattern.text or ""
        involved = set(events) if placeholders(tree) else set()
        for letter in sorted(event_letters(tree)):
            if letter in events:
                involved.add(letter)
            else:
                message = f"pattern names event '{letter}', which is not in events"
                self.at_text(pattern, "pattern-unknown-event", message, raw.find(letter))
        holes = placeholders(tree)
        if len(holes) > len(events):
            message = (
                f"pattern has {len(holes)} placeholders ({', '.join(sorted(holes))}) but its "
                f"<temporal> has {len(events)} events to bind them to"
            )
            self.at_text(pattern, "pattern-too-few-events", message, token.offset)
        return involved

    def check_condition(self, element: etree._Element) -> None:
        topics = children(element, "topic")
        for topic in topics:
            self.check_name(topic, "topic")
        own = element_text(topics[0]).text if topics else None
        for value in children(element, "value"):
            try:
                expression = parse_expression(value.text or "")
            except ExpressionError as error:
                self.at_text(value, "bad-expression", f"expression: {error.message}", error.offset)
                continue
            operands = topic_operands(expression)
            if not fields(expression) and not operands:
                message = (
                    "the condition reads no field of its topic: it holds always or never; "
                    "name a field (e.g. 'data == 1')"
                )
                self.at_element(value, "constant-condition", message)
            for name in sorted(operands - {own}) if own else ():
                message = (
                    f"the topic operand {name} is not the condition's topic {own}; a condition "
                    f"reads one topic"
                )
                self.at_element(value, "foreign-topic-operand", message)

    def check_detect(self, detect: etree._Element) -> None:
        window = detect.get("window")
        try:
            seconds = float(window) if window is not None else None
        except ValueError:  # the grammar says so
            return
        if seconds is not None and 0 < seconds < MIN_WINDOW:
            message = (
                f"window {window} s is below the resolution of the bags' timestamps as seconds "
                f"({MIN_WINDOW:g} s): no window would hold a message"
            )
            self.at_attribute(detect, "window", "window-below-resolution", message)

    def check_check(self, check: etree._Element) -> None:
        successes, fails = children(check, "success"), children(check, "fail")
        for fail in fails:
            self.check_onset(fail)
        if check.get("threshold") is not None and check.get("select", "cover") != "fscore":
            message = (
                'threshold applies to select="fscore" only; classification selects by cover '
                '(the default): add select="fscore" or remove threshold'
            )
            self.at_attribute(check, "threshold", "threshold-unused", message)
        bags = children(check, "bag")
        if (successes or fails) and bags:
            message = "<check> classifies with <success>/<fail> or compares with <bag>, not both"
            self.at_element(bags[0], "check-mixed", message)
        elif bags:
            return
        elif not successes and not fails:
            message = "<check> has no bags: give <success> and <fail>, or <bag>"
            self.at_element(check, "check-incomplete", message)
        elif not fails or not successes:
            missing = "fail" if not fails else "success"
            message = (
                f"<check> has no <{missing}> runs: classification needs both successful and "
                f"failed runs to score invariants"
            )
            self.at_element(check, "check-incomplete", message)

    def check_onset(self, fail: etree._Element) -> None:
        given = [name for name in ONSET_ATTRIBUTES if fail.get(name) is not None]
        if len(given) > 1:
            message = (
                f"<fail> gives its onset {len(given)} ways ({', '.join(given)}); "
                f"keep one of onset, onset_topic and onsets"
            )
            self.at_attribute(fail, given[1], "onset-conflict", message)
        topic = fail.get("onset_topic")
        if topic is not None:
            token = topic.strip()
            start = topic.index(token) if token else 0
            for problem in check_graph_name(token, "onset topic"):
                offset = start + problem.offset
                self.at_attribute(fail, "onset_topic", problem.code, problem.message, offset)
        if fail.get("onsets") is not None and not fail.get("onsets", "").strip():
            self.at_attribute(fail, "onsets", "invalid-value", "onsets names no file")

    def check_monitor(self, monitor: etree._Element, root: etree._Element) -> None:
        sources = [monitor, *children(root, "check"), *children(root, "detect")]
        if not any((source.get("inv") or "").strip() for source in sources):
            message = "<monitor> has no invariants file: set inv on it, on <check> or <detect>"
            self.at_element(monitor, "monitor-without-invariants", message)
        for block in children(monitor, "block"):
            self.check_block(block)
        for action in children(monitor, "action"):
            self.check_action(action)
        for violation in children(monitor, "violation"):
            self.check_violation(violation)

    def monitored_names(self) -> set[str]:
        names = set()
        for element in self.ids.values():
            if element.tag in EVENT_TAGS:
                child = "topic" if element.tag == "publish" else "service"
                text = element_text(element).text
                named = children(element, child)
                names.add(text or (element_text(named[0]).text if named else ""))
        return names

    def check_block(self, block: etree._Element) -> None:
        monitored = self.monitored_names()
        tokens = split_tokens(block.text or "", ", \t\r\n")
        if not tokens:
            self.at_element(block, "missing-topic", "<block> names no topic or service")
        for token in tokens:
            before = len(self.found)
            self.check_name(block, "blocked topic or service", token)
            if len(self.found) == before and token.text not in monitored:
                message = f"'{token.text}' is blocked but no <publish> or <call> monitors it"
                self.at_text(block, "unmonitored-block", message, token.offset)

    def check_action(self, action: etree._Element) -> None:
        for topic in children(action, "topic"):
            self.check_name(topic, "topic")
        for service in children(action, "service"):
            self.check_name(service, "service")
        for value in children(action, "value"):
            try:
                parse_flow_mapping(value.text or "")
            except FlowMapError as error:
                message = f"action value: {error.message}"
                self.at_text(value, "bad-action-value", message, error.offset)

    def check_violation(self, violation: etree._Element) -> None:
        raw = violation.text or ""
        shape = _VIOLATION.match(raw)
        if shape is None or not shape.group("points").strip():
            message = "violation must read POINTS -> ACTIONS, e.g. 'a,c,e -> f'"
            self.at_text(violation, "bad-violation", message, element_text(violation).offset)
            return
        for group, kinds in (("points", POINT_TAGS), ("actions", ("action",))):
            tokens = split_tokens(shape.group(group))
            if not tokens:
                message = "violation names no action after '->'"
                self.at_text(violation, "bad-violation", message, shape.start(group))
            for token in tokens:
                self.resolve_text(violation, shape.start(group) + token.offset, token, kinds)
                if group == "actions":
                    self.used_actions.add(token.text)

    def resolve_text(
        self, element: etree._Element, offset: int, token: Token, kinds: tuple[str, ...]
    ) -> None:
        what = " or ".join(f"<{k}>" for k in kinds)
        target = self.ids.get(token.text)
        if not token.text or not _LETTER_ID.fullmatch(token.text):
            message = f"{token.text!r} is not an id; write POINTS -> ACTIONS, e.g. 'a,c -> f'"
            self.at_text(element, "bad-violation", message, offset)
        elif target is None:
            message = f"violation names '{token.text}', but no {what} has that id"
            self.at_text(element, "unknown-ref", message, offset)
        elif target.tag not in kinds:
            message = f"violation names '{token.text}', a <{target.tag}>; expected {what}"
            self.at_text(element, "wrong-ref-kind", message, offset)

    def report_unused(self) -> None:
        for ident, condition in self.conditions.items():
            if ident not in self.used_conditions:
                message = f"condition '{ident}' is not used by any conds"
                self.at_element(condition, "unused-condition", message)
        for ident, element in self.ids.items():
            if element.tag == "action" and ident not in self.used_actions:
                message = f"action '{ident}' is not taken by any <violation>"
                self.at_element(element, "unused-action", message)


MIN_WINDOW = 1e-6
"""The shortest time window: message times are float seconds since 1970, whose resolution is
about 0.24 us today (0.95 us in 2106); a window below it holds no message."""


def topic_operands(expr: Expr) -> frozenset[str]:
    """The topic names an expression uses as operands."""
    if isinstance(expr, Topic):
        return frozenset((expr.name,))
    if isinstance(expr, Unary):
        return topic_operands(expr.operand)
    if isinstance(expr, Binary):
        return topic_operands(expr.left) | topic_operands(expr.right)
    if isinstance(expr, Logical):
        return frozenset().union(*(topic_operands(operand) for operand in expr.operands))
    return frozenset()


def check_semantics(config: LoadedConfig) -> list[Diagnostic]:
    """Run every semantic check on a loaded configuration."""
    return _Pass(config).run()
