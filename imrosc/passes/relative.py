"""Relative-topic grouping (thesis 3.3): a publish point pairs its topic with its inputs.

The inputs at hop 1 are the topics the publishers of the monitored topic subscribe to; at
hop ``h`` those of the publishers of the hop ``h - 1`` topics; up to ``relative`` hops.
Explicit ``<topic>`` children join as declared inputs. A topic is grouped once, at its
smallest hop, so grouping ends on any graph, cyclic ones included.

>>> from imrosc import ir
>>> from imrosc.graph.model import Graph, Node
>>> graph = Graph({"/ctrl": Node("/ctrl", frozenset({"/cmd"}), frozenset({"/pose"}), frozenset()),
...                "/loc": Node("/loc", frozenset({"/pose"}), frozenset({"/gps"}), frozenset())},
...               ("file",), True)
>>> point = ir.PublishPoint("a", "/cmd", ir.Span(3, 5), relative=2)
>>> project = ir.Project("p", "p.xml", ir.Span(1, 1), points=(point,))
>>> [(t.name, t.hops) for t in group_relative(project, PassContext(graph=graph)).points[0].inputs]
[('/pose', 1), ('/gps', 2)]
"""

from __future__ import annotations

import dataclasses

from imrosc import ir
from imrosc.graph.model import Graph
from imrosc.passes.context import PassContext


def _subscriptions(graph: Graph, topic: str) -> set[str]:
    """Topics the publishers of ``topic`` subscribe to."""
    return {
        input_topic
        for node in graph.publishers(topic)
        for input_topic in graph.nodes[node].subscribes
    }


def _group(point: ir.PublishPoint, graph: Graph, context: PassContext) -> ir.PublishPoint:
    hops = {point.topic: 0}
    frontier = [point.topic]
    cycles: set[str] = set()
    for hop in range(1, point.relative + 1):
        found = sorted({t for topic in frontier for t in _subscriptions(graph, topic)})
        cycles |= {t for t in found if t in hops}
        frontier = [t for t in found if t not in hops]
        hops.update(dict.fromkeys(frontier, hop))
        if not frontier:
            break
    for topic in sorted(cycles):
        context.report(
            point.span,
            "relative-cycle",
            f"grouping of {point.topic} reached {topic} again through the graph; "
            f"it is grouped once, at hop {hops[topic]}",
        )
    inputs = [ir.InputTopic(t, h) for t, h in hops.items() if h > 0]
    return dataclasses.replace(point, inputs=_with_explicit(inputs, point.explicit_topics))


def _with_explicit(
    inputs: list[ir.InputTopic], explicit: tuple[str, ...]
) -> tuple[ir.InputTopic, ...]:
    by_name = {i.name: i for i in inputs}
    for name in explicit:
        found = by_name.get(name)
        by_name[name] = ir.InputTopic(name, found.hops if found else 1, explicit=True)
    return tuple(sorted(by_name.values(), key=lambda i: (i.hops, i.name)))


def group_relative(project: ir.Project, context: PassContext) -> ir.Project:
    """Fill the ``inputs`` of every publish point from the graph and its explicit topics."""
    points: list[ir.Point] = []
    for point in project.points:
        points.append(_grouped(point, context) if isinstance(point, ir.PublishPoint) else point)
    return dataclasses.replace(project, points=tuple(points))


def _grouped(point: ir.PublishPoint, context: PassContext) -> ir.PublishPoint:
    if point.relative <= 0:
        return dataclasses.replace(point, inputs=_with_explicit([], point.explicit_topics))
    graph = context.graph
    if graph is None or not graph.knows_subscriptions:
        have = "no graph source" if graph is None else "a graph without subscriptions ("
        have += "" if graph is None else ", ".join(graph.sources) + ")"
        context.report(
            point.span,
            "relative-without-graph",
            f"relative={point.relative} on {point.topic} needs to know who subscribes to what, "
            f"but there is {have}: record with 'imrosc record' (build reads those bags "
            f"with --bags) or pass --graph FILE",
        )
        return dataclasses.replace(point, inputs=_with_explicit([], point.explicit_topics))
    if not graph.publishers(point.topic):
        context.report(
            point.span,
            "unknown-topic",
            f"the graph knows no publisher of {point.topic}, so its inputs cannot be grouped",
        )
        return dataclasses.replace(point, inputs=_with_explicit([], point.explicit_topics))
    return _group(point, graph, context)
