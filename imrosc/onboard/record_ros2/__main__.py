"""The recorder node as ``imrosc record`` runs it on ROS 2: ``python -m
imrosc.onboard.record_ros2 SPEC``, under the ROS 2 Python (generated packages start
:mod:`.node` from their own ``recorder.py`` instead; this module is not copied).

``SPEC`` is the recorder spec of :mod:`.logic` (``services``, ``params``,
``period``) with the node's name (``node``), ``events`` (it says ``ready`` and its counts
on standard output) and ``wait`` (it publishes its first snapshots once the bag tap
subscribes to the record topics). Python 3.8 syntax.
"""

from __future__ import annotations

import contextlib
import json
import sys
from typing import List, Optional

from . import logic, node

try:  # only a ROS 2 system has it
    import rclpy  # type: ignore[import-not-found, unused-ignore]
except ImportError:  # pragma: no cover - exercised on ROS 2 systems only
    rclpy = None


def main(argv: Optional[List[str]] = None) -> None:
    """Run the recorder node until SIGINT or SIGTERM."""
    args = sys.argv[1:] if argv is None else argv
    if rclpy is None:
        sys.exit("imrosc recorder: rclpy is not importable; run it under the ROS 2 Python")
    try:
        spec = logic.check_spec(json.loads(args[0]))
    except (IndexError, ValueError) as error:
        sys.exit(f"imrosc recorder: {error}")
    node.init([])
    with contextlib.suppress(KeyboardInterrupt):  # stopped while it waited for the tap
        node.serve(str(spec["node"]), spec)


if __name__ == "__main__":
    main()
