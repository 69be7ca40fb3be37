#!/usr/bin/python3
"""The small ROS 1 system that ``tests/live/test_record.py`` records, and its service type.

Run as a script under Debian's ``/usr/bin/python3`` (where rospy lives) it is one of three
nodes; imported by pytest it gives the helpers that set them up (it imports no rospy then):

* ``server`` (``/sys/server``): serves ``/sys/scale`` (``imrosc_rec_test/Scale``:
  ``y = gain * x * k``, ``note = "ok"``; ``k = 0`` is refused), after ``~delay`` seconds
  (10 ms); publishes ``/sys/level`` (``std_msgs/Float64``) at 20 Hz;
* ``client`` (``/sys/client``): subscribes to ``/sys/level``, calls ``/sys/scale`` at 10 Hz
  with ``x`` among 0, 0.5, ..., 2 and ``k`` among 1, 2, 3 (``k = 0`` every ``--refuse-every``
  calls, when given), publishes the last ``y`` on ``/sys/cmd`` (``std_msgs/Float64``);
* ``extra`` (``/sys/extra``): subscribes to ``/sys/level``, publishes ``/sys/beat``
  (``std_msgs/UInt8``) at 5 Hz; the test kills it in the middle of a recording.

``--service``, ``--level`` and ``--cmd`` give other names to ``/sys/scale``, ``/sys/level``
and ``/sys/cmd`` (for a second system started with roslaunch).

The service type is generated with genpy (:func:`generate_service_type`) into a folder that
goes on the ``PYTHONPATH`` of the nodes and of the recording node, as a catkin workspace's
``devel/lib/python3/dist-packages`` would.
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

SCRIPT = Path(__file__).resolve()
PACKAGE = "imrosc_rec_test"
SERVICE_TYPE = f"{PACKAGE}/Scale"
SERVICE_TEXT = "float64 x\nint32 k\n---\nfloat64 y\nstring note\n"
XS = (0.0, 0.5, 1.0, 1.5, 2.0)
KS = (1, 2, 3)
GAIN = 2.0

_GENERATE = """
import sys, genpy.generator
source, out = sys.argv[1], sys.argv[2]
status = genpy.generator.SrvGenerator().generate_messages(
    "imrosc_rec_test", [source], out, {"std_msgs": ["/usr/share/std_msgs/msg"]})
sys.exit(status)
"""


def generate_service_type(root: Path, python: str = "/usr/bin/python3") -> Path:
    """Generate the Python module of ``imrosc_rec_test/Scale`` under ``root``; returns the
    folder to put on ``PYTHONPATH``."""
    source = root / "srv" / "Scale.srv"
    source.parent.mkdir(parents=True, exist_ok=True)
    source.write_text(SERVICE_TEXT, encoding="utf-8")
    lib = root / "lib"
    out = lib / PACKAGE / "srv"
    out.mkdir(parents=True, exist_ok=True)
    subprocess.run(
        [python, "-c", _GENERATE, str(source), str(out)],
        check=True,
        capture_output=True,
        timeout=60,
    )
    (lib / PACKAGE / "__init__.py").write_text("", encoding="utf-8")
    (out / "__init__.py").write_text("from ._Scale import *\n", encoding="utf-8")
    return lib


def expected_y(x: float, k: int) -> float:
    """What the server answers."""
    return GAIN * x * k


# -- the nodes (run under /usr/bin/python3) -------------------------------------------------


def _server(rospy: Any, names: Any) -> None:
    from imrosc_rec_test.srv import Scale, ScaleResponse  # type: ignore[import-not-found, unused-ignore]
    from std_msgs.msg import Float64  # type: ignore[import-not-found, unused-ignore]

    rospy.init_node("server")
    if not rospy.has_param("~gain"):
        rospy.set_param("~gain", GAIN)
    delay = float(rospy.get_param("~delay", 0.01))

    def scale(request: Any) -> Any:
        if request.k == 0:
            raise rospy.ServiceException("k must not be 0")
        time.sleep(delay)
        gain = float(rospy.get_param("~gain", GAIN))
        return ScaleResponse(y=gain * request.x * request.k, note="ok")

    rospy.Service(names.service, Scale, scale)
    publisher = rospy.Publisher(names.level, Float64, queue_size=10)
    rate = rospy.Rate(20)
    step = 0
    while not rospy.is_shutdown():
        publisher.publish(Float64(data=(step % 10) / 10.0))
        step += 1
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break


def _client(rospy: Any, names: Any) -> None:
    from imrosc_rec_test.srv import Scale  # type: ignore[import-not-found, unused-ignore]
    from std_msgs.msg import Float64  # type: ignore[import-not-found, unused-ignore]

    rospy.init_node("client")
    rospy.Subscriber(names.level, Float64, lambda message: None, queue_size=10)
    publisher = rospy.Publisher(names.cmd, Float64, queue_size=10)
    rate = rospy.Rate(10)
    call = 0
    last = 0.0
    while not rospy.is_shutdown():
        try:
            rospy.wait_for_service(names.service, timeout=0.5)
        except rospy.ROSException:
            continue
        except rospy.ROSInterruptException:
            break
        call += 1
        refuse = names.refuse_every and call % names.refuse_every == 0
        k = 0 if refuse else KS[call % len(KS)]
        with contextlib.suppress(rospy.ServiceException):
            last = rospy.ServiceProxy(names.service, Scale)(x=XS[call % len(XS)], k=k).y
        publisher.publish(Float64(data=last))
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break


def _extra(rospy: Any, names: Any) -> None:
    from std_msgs.msg import Float64, UInt8  # type: ignore[import-not-found, unused-ignore]

    rospy.init_node("extra")
    rospy.Subscriber(names.level, Float64, lambda message: None, queue_size=10)
    publisher = rospy.Publisher("/sys/beat", UInt8, queue_size=10)
    rate = rospy.Rate(5)
    while not rospy.is_shutdown():
        publisher.publish(UInt8(data=7))
        try:
            rate.sleep()
        except rospy.ROSInterruptException:
            break


def main(argv: list[str]) -> None:
    """``record_support.py server|client|extra [options] [ROS remappings]``."""
    import argparse

    import rospy  # type: ignore[import-not-found, unused-ignore]

    parser = argparse.ArgumentParser(description="a node of the recorded test system")
    parser.add_argument("role", choices=("server", "client", "extra"))
    parser.add_argument("--service", default="/sys/scale")
    parser.add_argument("--level", default="/sys/level")
    parser.add_argument("--cmd", default="/sys/cmd")
    parser.add_argument("--refuse-every", type=int, default=0)
    names = parser.parse_args(rospy.myargv(argv=argv)[1:])
    {"server": _server, "client": _client, "extra": _extra}[names.role](rospy, names)


if __name__ == "__main__":
    main(sys.argv)
