"""The inference job (``job.json``): which bags to read, which families to instantiate at
each point, the tunables and where to write the invariants.

Backend ``plan`` writes it beside the plan (:mod:`imrosc.backends.plan`; ``imrosc infer``
builds the same in memory) and the translator takes each point's families from it
(:mod:`imrosc.translate.points`). The typed dictionaries below and the JSON schema
(``job.schema.json``: :func:`schema`) are kept in step by ``tests/formats/test_plan_job.py``;
the tunables are the IR's (``ir.Tunables`` in its JSON form), the families the catalog's
(:mod:`imrosc.runtime.families`).
"""

from __future__ import annotations

from typing import Any, TypedDict

from imrosc import formats

FORMAT = "imrosc-job"
VERSION = 1


def schema() -> dict[str, Any]:
    """The JSON schema of the format (draft 2020-12)."""
    return formats.schema(formats.JOB_SCHEMA)


class JobPoint(TypedDict):
    """The families inference instantiates at one point of the plan."""

    key: str
    kind: str
    families: list[str]


class Outputs(TypedDict):
    """Where inference writes: the invariants file (``None``: the configuration says none)."""

    invariants: str | None


JobDocument = TypedDict(
    "JobDocument",
    {
        "$comment": str,
        "format": str,
        "version": int,
        "project": str,
        "source": str,
        "plan": str,
        "bags": list[str],
        "tunables": dict[str, Any],
        "points": list[JobPoint],
        "outputs": Outputs,
    },
)
"""An inference job."""
