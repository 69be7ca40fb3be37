"""Puts every rospy process of the landing system in lockstep with the simulator.

This folder is on the ``PYTHONPATH`` of the graph's processes when ``LANDING_LOCKSTEP=1``
(``tests/live/landing_system.py`` sets both): Python imports this file at start-up, and it
has :mod:`rospy_lockstep` patch rospy as soon as rospy is imported. Without the variable, or
in an interpreter without rospy, it does nothing.

It also keeps the landing system's own nodes (the scripts of ``../nodes``) from importing
numpy, which none of them uses: genpy imports it when it can (to accept numpy's number types
in messages) and does without it otherwise, and it is about a third of the CPU time a rospy
node takes to start (the eleven processes of a trial start anew each trial).
"""

from __future__ import annotations

import os
import sys

NODES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "nodes")
if os.path.dirname(os.path.abspath(sys.argv[0] if sys.argv else "")) == NODES:
    sys.modules.setdefault("numpy", None)  # type: ignore[assignment]

if os.environ.get("LANDING_LOCKSTEP") == "1":
    import faulthandler
    import signal

    import rospy_lockstep

    faulthandler.register(signal.SIGUSR2)  # a stuck process tells where: kill -USR2 <pid>

    rospy_lockstep.patch_on_import()
