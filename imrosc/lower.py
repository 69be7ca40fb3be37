"""Lowering: a checked configuration tree becomes the IR, as written (no pass applied yet).

Lowering assumes ``imrosc check`` found no error: it reads the tree the grammar and the
semantic pass have vouched for, and only translates. Names stay as written (scope resolution
makes them global), ``relative`` is recorded but not followed (relative grouping does that),
conditional points are not yet expanded, and events not yet labelled.
"""

from __future__ import annotations

from collections.abc import Callable

from lxml import etree

from imrosc import ir
from imrosc.runtime.families import PUBLISH, select
from imrosc.schema import expression, pattern
from imrosc.schema.flowmap import parse_flow_mapping
from imrosc.schema.loader import LoadedConfig
from imrosc.schema.semantics import (
    ARCH_KINDS,
    FAMILY_SEPARATORS,
    children,
    element_text,
    split_tokens,
)


def _span(config: LoadedConfig, element: etree._Element) -> ir.Span:
    return ir.Span(*config.element_position(element))


def _ids(value: str | None) -> tuple[str, ...]:
    tokens = [token.text for token in split_tokens(value or "") if token.text]
    return tuple(dict.fromkeys(tokens))


def _texts(element: etree._Element, tag: str) -> tuple[str, ...]:
    return tuple(element_text(child).text for child in children(element, tag))


def _number(element: etree._Element, name: str, default: float) -> float:
    value = element.get(name)
    return default if value is None else float(value)


def _count(element: etree._Element, name: str, default: int) -> int:
    value = element.get(name)
    return default if value is None else int(value)


def _named(element: etree._Element, tag: str) -> tuple[str, tuple[str, ...]]:
    """The monitored name (text or first child) and the further children's names."""
    text = element_text(element).text
    named = _texts(element, tag)
    return (text, named) if text else (named[0], named[1:])


def _publish(config: LoadedConfig, element: etree._Element) -> ir.PublishPoint:
    topic, explicit = _named(element, "topic")
    return ir.PublishPoint(
        id=element.get("id", ""),
        topic=topic,
        span=_span(config, element),
        relative=_count(element, "relative", 0),
        explicit_topics=explicit,
        params=_texts(element, "param"),
        conds=_ids(element.get("conds")),
        families=_families(element.get("families")),
    )


def _families(value: str | None) -> tuple[str, ...]:
    """The families a checked ``families`` attribute selects (none: every family)."""
    if value is None:
        return ()
    chosen, _ = select([t.text for t in split_tokens(value, FAMILY_SEPARATORS)], PUBLISH)
    return chosen


def _call(config: LoadedConfig, element: etree._Element) -> ir.CallPoint:
    service, _ = _named(element, "service")
    return ir.CallPoint(
        id=element.get("id", ""),
        service=service,
        span=_span(config, element),
        params=_texts(element, "param"),
        conds=_ids(element.get("conds")),
    )


def _param(config: LoadedConfig, element: etree._Element) -> ir.ParamPoint:
    return ir.ParamPoint(
        id=element.get("id"),
        name=element_text(element).text,
        span=_span(config, element),
        conds=_ids(element.get("conds")),
    )


def _arch(config: LoadedConfig, element: etree._Element) -> ir.ArchPoint:
    written = set(_ids(element.text))
    kinds = tuple(kind for kind in ARCH_KINDS if kind in written) or ARCH_KINDS
    return ir.ArchPoint(
        id=element.get("id", ""),
        kinds=kinds,
        span=_span(config, element),
        conds=_ids(element.get("conds")),
    )


def _temporal(config: LoadedConfig, element: etree._Element) -> ir.TemporalPoint:
    patterns = tuple(
        ir.PatternSpec(
            text=element_text(child).text,
            canonical=pattern.to_text(pattern.parse_pattern(child.text or "")),
            span=_span(config, child),
        )
        for child in children(element, "pattern")
    )
    return ir.TemporalPoint(
        id=element.get("id", ""),
        events=_ids(element.get("events")),
        span=_span(config, element),
        max_interval=_number(element, "max_interval", 2.0),
        max_events=_count(element, "max_events", 10),
        patterns=patterns,
        conds=_ids(element.get("conds")),
    )


def _condition(config: LoadedConfig, element: etree._Element) -> ir.Condition:
    (topic,) = _texts(element, "topic")
    (text,) = _texts(element, "value")
    return ir.Condition(
        id=element.get("id") or element.get("label") or "",
        topic=topic,
        text=text,
        expression=ir.freeze(expression.to_json(expression.parse_expression(text))),
        span=_span(config, element),
    )


_POINT_LOWERINGS: dict[str, Callable[[LoadedConfig, etree._Element], ir.Point]] = {
    "publish": _publish,
    "call": _call,
    "param": _param,
    "arch": _arch,
    "temporal": _temporal,
}


def _detect(config: LoadedConfig, element: etree._Element) -> ir.Detect:
    defaults = ir.Tunables()
    tunables = ir.Tunables(
        window=_number(element, "window", defaults.window),
        confidence=_number(element, "confidence", defaults.confidence),
        drop_ratio=_number(element, "drop_ratio", defaults.drop_ratio),
        hull_chunk=_count(element, "hull_chunk", defaults.hull_chunk),
        discrete=_count(element, "discrete", defaults.discrete),
        budget=_number(element, "budget", defaults.budget),
        step_tail="larger" if element.get("step_tail") == "larger" else "select",
    )
    return ir.Detect(
        element.get("inv", ""), _texts(element, "bag"), _span(config, element), tunables
    )


def _check(config: LoadedConfig, element: etree._Element, fallback: str) -> ir.Check:
    success, fail = _texts(element, "success"), _texts(element, "fail")
    return ir.Check(
        inv=(element.get("inv") or fallback).strip(),
        mode="classify" if success or fail else "compare",
        span=_span(config, element),
        success=success,
        fail=fail,
        bags=_texts(element, "bag"),
        threshold=_number(element, "threshold", 0.5),
        beta=_number(element, "beta", 1.0),
        onsets=tuple(_onset(config, child) for child in children(element, "fail")),
        select="fscore" if element.get("select") == "fscore" else "cover",
        detector="none" if element.get("detector") == "none" else "logistic",
    )


def _onset(config: LoadedConfig, element: etree._Element) -> ir.Onset:
    seconds, topic, file = (element.get(name) for name in ("onset", "onset_topic", "onsets"))
    return ir.Onset(
        span=_span(config, element),
        seconds=None if seconds is None else float(seconds),
        topic=None if topic is None else topic.strip(),
        file=None if file is None else file.strip(),
    )


def _action(config: LoadedConfig, element: etree._Element) -> ir.Action:
    topics, services = _texts(element, "topic"), _texts(element, "service")
    values = _texts(element, "value")
    return ir.Action(
        id=element.get("id", ""),
        target="topic" if topics else "service",
        name=(topics or services)[0],
        value=ir.freeze(parse_flow_mapping(values[0])) if values else {},
        span=_span(config, element),
    )


def _monitor(config: LoadedConfig, element: etree._Element, fallback: str) -> ir.Monitor:
    violations = []
    for child in children(element, "violation"):
        points, _, actions = (child.text or "").partition("->")
        violations.append(ir.Violation(_ids(points), _ids(actions), _span(config, child)))
    block = [
        token.text
        for child in children(element, "block")
        for token in split_tokens(child.text or "", ", \t\r\n")
        if token.text
    ]
    return ir.Monitor(
        inv=(element.get("inv") or fallback).strip(),
        span=_span(config, element),
        launch=(element.get("launch") or "").strip() or None,
        launch_ros2=(element.get("launch_ros2") or "").strip() or None,
        period=_number(element, "period", 1.0),
        block=tuple(dict.fromkeys(block)),
        actions=tuple(_action(config, child) for child in children(element, "action")),
        violations=tuple(violations),
        alarms=_alarms(element),
    )


def _alarms(element: etree._Element) -> ir.AlarmOverrides:
    """The ``alarm_*`` attributes of ``<monitor>`` (absent ones keep the file's rule)."""
    persist, seconds = element.get("alarm_persist"), element.get("alarm_seconds")
    distinct, window = element.get("alarm_distinct"), element.get("alarm_window")
    severe = element.get("alarm_severe")
    return ir.AlarmOverrides(
        persist=None if persist is None else int(persist),
        seconds=None if seconds is None else float(seconds),
        distinct=None if distinct is None else int(distinct),
        window=None if window is None else float(window),
        severe=None if severe is None else float(severe),
    )


def lower(config: LoadedConfig) -> ir.Project:
    """The IR of a configuration that ``imrosc check`` accepted."""
    root = config.root
    points: list[ir.Point] = []
    conditions: list[ir.Condition] = []
    for scope in children(root, "scope"):
        for element in scope:
            if element.tag == "condition":
                conditions.append(_condition(config, element))
            elif isinstance(element.tag, str) and element.tag in _POINT_LOWERINGS:
                points.append(_POINT_LOWERINGS[element.tag](config, element))
    detects = [_detect(config, element) for element in children(root, "detect")]
    detect = detects[0] if detects else None
    checks = [_check(config, e, detect.inv if detect else "") for e in children(root, "check")]
    check = checks[0] if checks else None
    fallback = check.inv if check else detect.inv if detect else ""
    monitors = [_monitor(config, element, fallback) for element in children(root, "monitor")]
    return ir.Project(
        name=root.get("project", "").strip(),
        source=config.path,
        span=_span(config, root),
        points=tuple(points),
        conditions=tuple(conditions),
        detect=detect,
        check=check,
        monitor=monitors[0] if monitors else None,
    )
