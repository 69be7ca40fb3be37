"""The plan's and the job's typed dictionaries (``imrosc.formats``) name the keys their JSON
schemas (``imrosc/backends/schemas/``) name, and what the backend writes is that format."""

from __future__ import annotations

from pathlib import Path
from typing import get_type_hints

from imrosc.backends.plan import render_job, render_plan
from imrosc.backends.registry import BuildInputs
from imrosc.formats import job, plan
from imrosc.frontend import compile_config
from tests.formats.support import same_keys

ROOT = Path(__file__).resolve().parent.parent.parent


def test_the_plan_s_typed_dictionaries_are_its_schema() -> None:
    schema = plan.schema()
    assert schema["properties"]["format"]["const"] == plan.FORMAT
    assert schema["properties"]["version"]["const"] == plan.VERSION
    same_keys(plan.PlanDocument, schema)
    same_keys(plan.PlanTopic, schema["properties"]["topics"]["additionalProperties"])
    same_keys(plan.PlanCondition, schema["properties"]["conditions"]["items"])
    branches = schema["properties"]["points"]["items"]["oneOf"]
    assert [b["properties"]["kind"]["const"] for b in branches] == list(plan.POINT_FORMS)
    for branch in branches:
        form = plan.POINT_FORMS[branch["properties"]["kind"]["const"]]
        same_keys(form, branch)
        hints = get_type_hints(form)
        same_keys(hints["trigger"], branch["properties"]["trigger"])
        condition = branch["properties"]["condition"]["anyOf"][0]
        same_keys(plan.PointCondition, condition)
    publish, _, _, _, temporal = branches
    same_keys(plan.Input, publish["properties"]["inputs"]["items"])
    fields = publish["properties"]["variables"]["additionalProperties"]["oneOf"][1]["items"]
    same_keys(plan.Field, fields)
    same_keys(plan.Event, temporal["properties"]["events"]["items"])
    pattern = temporal["properties"]["patterns"]["items"]
    same_keys(plan.Pattern, pattern)
    same_keys(plan.Concrete, pattern["properties"]["concrete"]["items"])
    same_keys(plan.Thresholds, temporal["properties"]["thresholds"])


def test_the_job_s_typed_dictionaries_are_its_schema() -> None:
    schema = job.schema()
    assert schema["properties"]["format"]["const"] == job.FORMAT
    assert schema["properties"]["version"]["const"] == job.VERSION
    same_keys(job.JobDocument, schema)
    same_keys(job.JobPoint, schema["properties"]["points"]["items"])
    same_keys(job.Outputs, schema["properties"]["outputs"])


def test_every_point_the_backend_writes_is_the_form_of_its_kind() -> None:
    compiled = compile_config(ROOT / "examples" / "landing_sim.xml", None)
    assert compiled.project is not None
    inputs = BuildInputs(compiled.project, ())
    rendered = render_plan(inputs)
    kinds = set()
    for point in rendered["points"]:
        kinds.add(point["kind"])
        assert set(point) == set(plan.POINT_FORMS[point["kind"]].__annotations__)
    assert kinds == set(plan.POINT_FORMS)
    assert [p["key"] for p in render_job(inputs)["points"]] == [
        p["key"] for p in rendered["points"]
    ]
