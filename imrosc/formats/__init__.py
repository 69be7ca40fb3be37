"""The files one stage hands the next, each typed where it is defined.

* the translator plan (``plan.json``): :mod:`imrosc.formats.plan`;
* the inference job (``job.json``): :mod:`imrosc.formats.job`;
* the invariants file (``.inv``): :mod:`imrosc.invariants`, a point's pairing
  :mod:`imrosc.runtime.points`;
* a monitor's ``spec.json``: :mod:`imrosc.backends.monitor` (``MonitorSpec``), read on the
  robot by :mod:`imrosc.onboard.files`;
* the records in bags (``/imrosc/arch``, ``/imrosc/params``, ``/imrosc/srvs``):
  :mod:`imrosc.onboard.records` writes them, :mod:`imrosc.records` reads them.

Each typed description is held to the format's JSON schema by a test (``tests/formats/``,
``tests/test_invariants_format.py``).
"""
