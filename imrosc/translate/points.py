"""Program-point specifications: the plan's points with their variables, given the catalog.

A publish point's variables are its topic's (``trigger=True``), then each input topic's, then
its parameters'; a call point's are the flattened request and response of its service, its
``delay`` and ``ok``; a parameter point has one variable; an architecture point one set
variable per kind and resource (``pubs(/t)``); a temporal point one ``event`` string.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from imrosc.formats.job import JobDocument
from imrosc.formats.plan import PlanDocument, PlanPoint
from imrosc.infer.core import Variable
from imrosc.runtime.points import Filter, Pairing
from imrosc.translate.catalog import Catalog, arch_resources
from imrosc.translate.condition import resolve_fields
from imrosc.translate.layout import TopicLayout, short_names, topic_layout

ARCH_VARIABLE = {"pub": "pubs", "sub": "subs", "srv": "srvs"}


class PlanError(ValueError):
    """A plan point that the bags cannot feed (e.g. a condition naming a missing field)."""


@dataclass(frozen=True)
class ConditionSpec:
    """A condition: its topic, expression and the variable each field path means."""

    id: str
    topic: str
    expression: Mapping[str, Any]
    fields: Mapping[tuple[Any, ...], str]


@dataclass(frozen=True)
class PointSpec:
    """Everything the translator needs to produce one point's samples."""

    key: str
    kind: str
    variables: tuple[Variable, ...]
    families: tuple[str, ...]
    trigger: str = ""
    inputs: tuple[str, ...] = ()
    params: tuple[str, ...] = ()
    condition: ConditionSpec | None = None
    arch: Mapping[str, tuple[str, ...]] | None = None
    events: tuple[tuple[str, str, str], ...] = ()
    patterns: tuple[Mapping[str, Any], ...] = ()
    max_interval: float = 2.0
    max_events: int = 10

    def pairing(self, *discovered: Filter) -> Pairing:
        """How the engine rebuilds this point's samples (the invariants file's record of it,
        :mod:`imrosc.runtime.points`): its inputs, parameters, events, its declared condition
        and the ``discovered`` ones inference adds."""
        filters = list(discovered)
        if self.condition is not None:
            condition = self.condition
            fields = tuple((tuple(path), name) for path, name in condition.fields.items())
            filters.insert(0, Filter(condition.id, condition.topic, condition.expression, fields))
        return Pairing(self.inputs, self.params, self.events, tuple(filters))


def _service_variables(catalog: Catalog, service: str, short: str) -> tuple[Variable, ...]:
    fields = catalog.services.get(service, {})
    found = [
        Variable(f"{short}.{path}", "string" if kind == "string" else "float", service, path)
        for path, kind in sorted(fields.items())
    ]
    found.append(Variable(f"{short}.delay", "float", service, "delay"))
    return tuple(found)


def _param_variable(catalog: Catalog, name: str, *, trigger: bool) -> Variable:
    kind = "string" if catalog.params.get(name) == "string" else "float"
    return Variable(name, kind, name, "", trigger=trigger)  # type: ignore[arg-type]


@dataclass
class PointBuilder:
    """Builds :class:`PointSpec` s of one plan against one catalog."""

    plan: PlanDocument
    catalog: Catalog

    def __post_init__(self) -> None:
        topics = set(self.catalog.types)
        for point in self.plan["points"]:
            if point["kind"] == "call":
                topics.add(point["trigger"]["service"])
        self.short = short_names(topics)
        self.layouts: dict[tuple[str, bool], TopicLayout] = {}

    def layout(self, topic: str, *, trigger: bool) -> TopicLayout | None:
        """The layout of a recorded topic (None if no bag has it)."""
        known = self.catalog.types.get(topic)
        if known is None:
            return None
        key = (topic, trigger)
        if key not in self.layouts:
            self.layouts[key] = topic_layout(
                topic, known[0], known[1], self.short[topic], trigger=trigger
            )
        return self.layouts[key]

    def condition(self, point: PlanPoint) -> ConditionSpec | None:
        data = point["condition"]
        if not data:
            return None
        layout = self.layout(data["topic"], trigger=False)
        if layout is None:
            raise PlanError(f"condition {data['id']}: no bag records its topic {data['topic']}")
        names = [v.name for v in layout.variables]
        try:
            fields = resolve_fields(
                data["expression"], data["topic"], self.short[data["topic"]], names
            )
        except ValueError as error:
            raise PlanError(f"condition {data['id']}: {error}") from None
        return ConditionSpec(data["id"], data["topic"], data["expression"], fields)

    def build(self, point: PlanPoint, families: tuple[str, ...]) -> PointSpec:
        common: dict[str, Any] = {
            "key": point["key"],
            "kind": point["kind"],
            "families": families,
            "condition": self.condition(point),
        }
        if point["kind"] == "publish":
            topic = point["trigger"]["topic"]
            inputs = tuple(i["topic"] for i in point["inputs"] if i["topic"] in self.catalog.types)
            variables: list[Variable] = []
            for name, trigger in ((topic, True), *((i, False) for i in inputs)):
                layout = self.layout(name, trigger=trigger)
                variables += layout.variables if layout else ()
            params = tuple(point["params"])
            variables += [_param_variable(self.catalog, p, trigger=False) for p in params]
            return PointSpec(
                variables=tuple(variables), trigger=topic, inputs=inputs, params=params, **common
            )
        if point["kind"] == "call":
            service = point["trigger"]["service"]
            short = self.short[service]
            params = tuple(point["params"])
            variables = [*_service_variables(self.catalog, service, short)]
            variables += [_param_variable(self.catalog, p, trigger=False) for p in params]
            return PointSpec(variables=tuple(variables), trigger=service, params=params, **common)
        if point["kind"] == "param":
            name = point["trigger"]["param"]
            variable = _param_variable(self.catalog, name, trigger=True)
            return PointSpec(variables=(variable,), trigger=name, **common)
        if point["kind"] == "arch":
            resources = arch_resources(self.catalog, point["trigger"]["architecture"])
            variables = [
                Variable(f"{ARCH_VARIABLE[k]}({r})", "set", r, k)
                for k, names in resources.items()
                for r in names
            ]
            arch = {k: tuple(names) for k, names in resources.items()}
            return PointSpec(variables=tuple(variables), arch=arch, **common)
        events = tuple((e["id"], e["event"], e["name"]) for e in point["events"])
        thresholds = point["thresholds"]
        return PointSpec(
            variables=(Variable("event", "string"),),
            events=events,
            patterns=tuple(point["patterns"]),
            max_interval=float(thresholds["max_interval"]),
            max_events=int(thresholds["max_events"]),
            **common,
        )


def point_specs(
    plan: PlanDocument, job: JobDocument, catalog: Catalog
) -> tuple[list[PointSpec], list[str], dict[str, TopicLayout]]:
    """Specs of the plan points the bags can feed, a message per point they cannot, and the
    layout of every topic the specs read."""
    families = {p["key"]: tuple(p["families"]) for p in job["points"]}
    builder = PointBuilder(plan, catalog)
    specs: list[PointSpec] = []
    problems: list[str] = []
    for point in plan["points"]:
        try:
            specs.append(builder.build(point, families.get(point["key"], ())))
        except PlanError as error:
            problems.append(f"point {point['key']}: {error}")
    layouts = {topic: layout for (topic, _), layout in sorted(builder.layouts.items())}
    return specs, problems, layouts
