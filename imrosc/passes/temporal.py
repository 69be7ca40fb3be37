"""Temporal event labelling (thesis 3.4.4): events to names, placeholders to concrete events.

Each event id of a ``<temporal>`` becomes the publish or call it stands for. Each pattern's
uppercase placeholders are bound to every ordered choice of distinct events (Algorithm 9):
``(AB)*`` over events a, b, c gives six concrete patterns.

>>> from imrosc import ir
>>> points = (ir.PublishPoint("a", "/x", ir.Span(2, 1)), ir.PublishPoint("b", "/y", ir.Span(3, 1)),
...           ir.CallPoint("c", "/s", ir.Span(4, 1)),
...           ir.TemporalPoint("e", ("a", "b", "c"), ir.Span(5, 1),
...                            patterns=(ir.PatternSpec("(AB)*", "(AB)*", ir.Span(6, 1)),)))
>>> project = label_events(ir.Project("p", "p.xml", ir.Span(1, 1), points=points), PassContext())
>>> [c.text for c in project.points[3].patterns[0].concrete]
['(ab)*', '(ac)*', '(ba)*', '(bc)*', '(ca)*', '(cb)*']
"""

from __future__ import annotations

import dataclasses
import itertools

from imrosc import ir
from imrosc.passes.context import PassContext
from imrosc.schema import pattern as rx


def render(tree: rx.Pattern, binding: dict[str, str]) -> str:
    """The pattern with placeholders replaced by event ids (``<id>`` for a longer id)."""
    letters = {hole: event for hole, event in binding.items() if len(event) == 1}
    text = rx.to_text(rx.substitute(tree, letters))
    for hole, event in binding.items():
        if len(event) > 1:
            text = text.replace(hole, f"<{event}>")
    return text


def _concrete(spec: ir.PatternSpec, events: tuple[str, ...]) -> ir.PatternSpec:
    tree = rx.parse_pattern(spec.text)
    holes = sorted(rx.placeholders(tree))
    concrete = tuple(
        ir.ConcretePattern(
            tuple(zip(holes, chosen, strict=True)),
            render(tree, dict(zip(holes, chosen, strict=True))),
        )
        for chosen in itertools.permutations(events, len(holes))
    )
    return dataclasses.replace(spec, concrete=concrete)


def _labelled(point: ir.TemporalPoint, by_id: dict[str | None, ir.Point]) -> ir.TemporalPoint:
    labels = []
    for event in point.events:
        target = by_id.get(event)
        if isinstance(target, ir.PublishPoint):
            labels.append(ir.EventLabel(event, "publish", target.topic))
        elif isinstance(target, ir.CallPoint):
            labels.append(ir.EventLabel(event, "call", target.service))
    events = tuple(label.id for label in labels)
    return dataclasses.replace(
        point,
        labels=tuple(labels),
        patterns=tuple(_concrete(spec, events) for spec in point.patterns),
    )


def label_events(project: ir.Project, context: PassContext) -> ir.Project:
    """Label every temporal point's events and bind its patterns' placeholders."""
    by_id: dict[str | None, ir.Point] = {p.id: p for p in project.points if p.condition is None}
    points = tuple(
        _labelled(p, by_id) if isinstance(p, ir.TemporalPoint) else p for p in project.points
    )
    return dataclasses.replace(project, points=points)
