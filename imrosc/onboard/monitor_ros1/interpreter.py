"""Run a generated ROS 1 script under a Python that has rospy.

The scripts start with ``#!/usr/bin/env python3``, which is whatever ``python3`` comes first on
``PATH``: with a virtualenv active (imrosc itself is often installed in one), that Python has
no rospy, which lives in the system's ``/usr/bin/python3`` (Debian's ``python3-rospy``, ROS
Noetic's packages). :func:`ensure_rospy` re-executes the script once under the system's
Python when rospy cannot be imported here and can be there; otherwise it says in one line
what to do and exits with status 1. Python 3.8 syntax, standard library only.
"""

import os
import subprocess
import sys
from typing import List, Sequence

SYSTEM_PYTHONS = ("/usr/bin/python3",)
"""Where ROS 1's Python is on the systems it ships for."""
AGAIN = "IMROSC_ROSPY_REEXEC"
"""Set in the environment of the re-executed script: it is not re-executed twice."""


def has_rospy(python: str) -> bool:
    """Whether ``python`` imports rospy (asked in a child process, as quietly as can be)."""
    try:
        done = subprocess.run(
            [python, "-c", "import rospy"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            timeout=30,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return False
    return done.returncode == 0


def candidates(current: str, pythons: Sequence[str] = SYSTEM_PYTHONS) -> List[str]:
    """The system Pythons worth trying: present, executable and not ``current`` itself.

    >>> candidates("/usr/bin/python3", ["/usr/bin/python3"])
    []
    """
    here = os.path.realpath(current)
    return [
        python
        for python in pythons
        if os.access(python, os.X_OK) and os.path.realpath(python) != here
    ]


def ensure_rospy(argv: Sequence[str]) -> None:
    """Return when rospy imports here; else re-execute ``argv`` under a system Python that
    has it, or exit 1 with one line saying what to do."""
    try:
        import rospy  # type: ignore[import-not-found, unused-ignore]  # noqa: F401

        return
    except ImportError:
        pass
    if not os.environ.get(AGAIN):
        for python in candidates(sys.executable):
            if has_rospy(python):
                os.environ[AGAIN] = "1"
                os.execv(python, [python, *argv])
    script = argv[0] if argv else "the script"
    sys.stderr.write(
        f"{script}: rospy cannot be imported by {sys.executable} (a virtualenv?); run it with "
        f"ROS 1's Python, e.g. /usr/bin/python3 {script}, or from a shell where ROS 1 is "
        "sourced and no virtualenv is active\n"
    )
    sys.exit(1)
