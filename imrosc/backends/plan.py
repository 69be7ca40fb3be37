"""Backend ``plan``: the translator plan and the inference job, as versioned JSON.

``plan.json`` tells the translator what to read from the bags for each program point: the
trigger, the input topics with their hop distance, the variables to extract (field lists when
the bags gave the message types, ``"*"`` for all otherwise), condition predicates, and the
record topics for services, parameters and the architecture. ``job.json`` tells inference
which bags to read, which template families to instantiate at each point, the tunables and
where to write the invariants. Both formats are typed in :mod:`imrosc.formats.plan` and
:mod:`imrosc.formats.job`; ``plan.schema.json`` and ``job.schema.json`` (shipped beside this
module) describe them.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any, Literal

from imrosc import ir, records
from imrosc.backends.families import families
from imrosc.backends.registry import BuildInputs, register
from imrosc.formats import job, plan

PLAN_VERSION = plan.VERSION
JOB_VERSION = job.VERSION


def _dump(document: Mapping[str, Any]) -> bytes:
    return (json.dumps(document, indent=2, ensure_ascii=False) + "\n").encode("utf-8")


def _variables(inputs: BuildInputs, topic: str) -> list[plan.Field] | Literal["*"]:
    known = inputs.topic_types.get(topic)
    if known is None:
        return "*"
    return [
        {"path": f.path, "type": f.type, "array": f.array, "length": f.length} for f in known.fields
    ]


def _condition(project: ir.Project, point: ir.Point) -> plan.PointCondition | None:
    if point.condition is None:
        return None
    condition = project.condition(point.condition)
    return {
        "id": condition.id,
        "topic": condition.topic,
        "text": condition.text,
        "expression": ir.to_json(condition.expression),
        "discovered": condition.discovered,
    }


def _point(inputs: BuildInputs, point: ir.Point) -> plan.PlanPoint:
    key, ident = ir.point_key(point), point.id
    condition = _condition(inputs.project, point)
    if isinstance(point, ir.PublishPoint):
        topics = [point.topic, *(i.name for i in point.inputs)]
        return {
            "key": key,
            "id": ident,
            "kind": "publish",
            "trigger": {"topic": point.topic},
            "inputs": [
                {"topic": i.name, "hops": i.hops, "explicit": i.explicit} for i in point.inputs
            ],
            "variables": {topic: _variables(inputs, topic) for topic in topics},
            "params": list(point.params),
            "condition": condition,
        }
    if isinstance(point, ir.CallPoint):
        return {
            "key": key,
            "id": ident,
            "kind": "call",
            "trigger": {"service": point.service},
            "records": records.SRVS_TOPIC,
            "variables": ["request.*", "response.*", "delay"],
            "params": list(point.params),
            "condition": condition,
        }
    if isinstance(point, ir.ParamPoint):
        return {
            "key": key,
            "id": ident,
            "kind": "param",
            "trigger": {"param": point.name},
            "records": records.PARAMS_TOPIC,
            "condition": condition,
        }
    if isinstance(point, ir.ArchPoint):
        return {
            "key": key,
            "id": ident,
            "kind": "arch",
            "trigger": {"architecture": list(point.kinds)},
            "records": records.ARCH_TOPIC,
            "condition": condition,
        }
    return {
        "key": key,
        "id": ident,
        "kind": "temporal",
        "trigger": {"events": [label.id for label in point.labels]},
        "events": [
            {"id": label.id, "event": label.event, "name": label.name} for label in point.labels
        ],
        "patterns": [
            {
                "text": spec.text,
                "canonical": spec.canonical,
                "concrete": [{"binding": dict(c.binding), "text": c.text} for c in spec.concrete],
            }
            for spec in point.patterns
        ],
        "thresholds": {"max_interval": point.max_interval, "max_events": point.max_events},
        "condition": condition,
    }


def _topics(inputs: BuildInputs) -> dict[str, plan.PlanTopic]:
    return {topic: {"type": known.msgtype} for topic, known in sorted(inputs.topic_types.items())}


def render_plan(inputs: BuildInputs) -> plan.PlanDocument:
    """The translator plan as a JSON document."""
    project = inputs.project
    return {
        "$comment": inputs.banner("plan"),
        "format": plan.FORMAT,
        "version": plan.VERSION,
        "project": project.name,
        "source": project.source,
        "passes": list(project.passes),
        "topics": _topics(inputs),
        "conditions": [
            {"id": c.id, "topic": c.topic, "text": c.text, "discovered": c.discovered}
            for c in project.conditions
        ],
        "points": [_point(inputs, point) for point in project.points],
    }


def render_job(inputs: BuildInputs) -> job.JobDocument:
    """The inference job as a JSON document."""
    project = inputs.project
    detect = project.detect
    tunables = detect.tunables if detect else ir.Tunables()
    return {
        "$comment": inputs.banner("plan"),
        "format": job.FORMAT,
        "version": job.VERSION,
        "project": project.name,
        "source": project.source,
        "plan": "plan.json",
        "bags": list(inputs.bags or (detect.bags if detect else ())),
        "tunables": ir.to_json(tunables),
        "points": [
            {"key": ir.point_key(point), "kind": point.kind, "families": list(families(point))}
            for point in project.points
        ],
        "outputs": {"invariants": detect.inv if detect else None},
    }


@register("plan")
def render(inputs: BuildInputs) -> dict[str, bytes]:
    """``plan.json`` and ``job.json``."""
    return {"plan.json": _dump(render_plan(inputs)), "job.json": _dump(render_job(inputs))}
