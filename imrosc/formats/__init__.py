"""The files one stage hands the next, each typed where it is defined.

* the translator plan (``plan.json``): :mod:`imrosc.formats.plan`;
* the inference job (``job.json``): :mod:`imrosc.formats.job`;
* the invariants file (``.inv``): :mod:`imrosc.invariants`, a point's pairing
  :mod:`imrosc.runtime.points`;
* a monitor's ``spec.json``: :mod:`imrosc.backends.monitor` (``MonitorSpec``), read on the
  robot by :mod:`imrosc.onboard.files`;
* the records in bags (``/imrosc/arch``, ``/imrosc/params``, ``/imrosc/srvs``):
  :mod:`imrosc.onboard.records` types and writes them, :mod:`imrosc.records` reads them.

Each typed description is held to the format's JSON schema by a test (``tests/formats/``,
``tests/test_invariants_format.py``); the schemas of the plan, the job, the monitor spec
and the records are shipped in ``imrosc/backends/schemas/`` (:func:`schema`).
"""

from __future__ import annotations

import json
from importlib import resources
from typing import Any

PLAN_SCHEMA = "plan.schema.json"
JOB_SCHEMA = "job.schema.json"
SPEC_SCHEMA = "spec.schema.json"
RECORDS_SCHEMA = "records.schema.json"


def schema(name: str) -> dict[str, Any]:
    """A JSON schema of ``imrosc/backends/schemas/`` (draft 2020-12), by file name."""
    folder = resources.files("imrosc.backends").joinpath("schemas")
    found: dict[str, Any] = json.loads(folder.joinpath(name).read_text(encoding="utf-8"))
    return found
