"""Puts every rospy process of the landing system in lockstep with the simulator.

This folder is on the ``PYTHONPATH`` of the graph's processes when ``LANDING_LOCKSTEP=1``
(``tests/live/landing_system.py`` sets both): Python imports this file at start-up, and it
has :mod:`rospy_lockstep` patch rospy as soon as rospy is imported. Without the variable, or
in an interpreter without rospy, it does nothing.
"""

from __future__ import annotations

import os

if os.environ.get("LANDING_LOCKSTEP") == "1":
    import faulthandler
    import signal

    import rospy_lockstep

    faulthandler.register(signal.SIGUSR2)  # a stuck process tells where: kill -USR2 <pid>

    rospy_lockstep.patch_on_import()
