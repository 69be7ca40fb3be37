"""The generated ROS 1 monitor's fail-open watchdog on real ROS 1.

The monitor package of a small system (a blocked command topic ``/a/cmd`` and a relayed
service ``/a/reset``, the ROS 2 live tests' system) is built with ``--backend ros1``; its
watchdog runs alone, so the monitor's heartbeat is silent and it fails open: it relays
``/a/cmd`` to ``/m/a/cmd`` and serves ``/m/a/reset`` unchecked. A driver node plays the
system and then the monitor's heartbeat, which stops the relaying. ``served-late``: the
driver (and so ``/a/reset``) starts only once the watchdog failed open without finding the
service, which it must then pick up at a later tick.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.backends.monitor_support import build_ros1, config_text, write_case, write_package
from tests.backends.ros2_live_support import MONITOR, SCOPE, demo_document
from tests.live.harness import ROS_PYTHON, Ros, wait_until

pytestmark = pytest.mark.live

DRIVER = r"""
import json, time
import rosgraph, rospy
from std_msgs.msg import Time, UInt8
from std_srvs.srv import SetBool, SetBoolResponse

rospy.init_node("driver")
out = {"relayed": [], "served": []}

def serve(request):
    out["served"].append(bool(request.data))
    return SetBoolResponse(success=True, message="done")

def wait(what, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end and not rospy.is_shutdown():
        if what():
            return True
        time.sleep(0.05)
    return False

master = rosgraph.Master(rospy.get_name())

def relays_service():
    try:
        master.lookupService("/m/a/reset")
        return True
    except Exception:
        return False

rospy.Service("/a/reset", SetBool, serve)
cmd = rospy.Publisher("/a/cmd", UInt8, queue_size=10)
rospy.Subscriber("/m/a/cmd", UInt8, lambda m: out["relayed"].append(m.data))
out["failed_open"] = wait(relays_service)
out["connected"] = wait(lambda: cmd.get_num_connections() > 0)
time.sleep(0.5)
cmd.publish(UInt8(data=9))  # unchecked while the monitor is silent
wait(lambda: 9 in out["relayed"], 10.0)
out["answer"] = None
if out["failed_open"]:
    out["answer"] = rospy.ServiceProxy("/m/a/reset", SetBool)(True).success
beat = rospy.Publisher("/m/heartbeat", Time, queue_size=1)  # the monitor is back

def beating():
    beat.publish(Time(data=rospy.Time.now()))
    return not relays_service()

out["stopped"] = wait(beating, 30.0)
print("@@out " + json.dumps(out), flush=True)
"""


@pytest.mark.parametrize("late", [False, True], ids=["served", "served-late"])
def test_the_watchdog_fails_open_while_the_monitor_is_silent(
    ros: Ros, tmp_path: Path, late: bool
) -> None:
    config = write_case(tmp_path, config_text(scope=SCOPE, monitor=MONITOR), demo_document())
    result = build_ros1(config)
    assert result.ok, [d.as_text() for d in result.diagnostics]
    package = write_package(result.files, tmp_path / "out")
    watchdog = ros.spawn(
        "watchdog", [str(ROS_PYTHON), str(package / "scripts" / "demo_monitor_watchdog")]
    )
    try:
        if late:  # failed open before /a/reset was served
            wait_until(
                lambda: "cannot relay /a/reset" in watchdog.tail(200),
                "the watchdog to fail open without /a/reset",
                30,
                (watchdog,),
            )
        driver = ros.spawn("driver", [str(ROS_PYTHON), "-c", DRIVER, "__ns:=/a"])
        driver.popen.wait(timeout=120)
    finally:
        ros.stop(watchdog)
    lines = [line for line in driver.tail(200).splitlines() if line.startswith("@@out ")]
    context = driver.tail(60) + "\n\n" + watchdog.tail(60)
    assert driver.popen.returncode == 0 and lines, context
    out = json.loads(lines[-1].split("@@out ", 1)[1])
    context = json.dumps(out) + "\n" + context
    assert out["failed_open"] and out["connected"], context
    assert 9 in out["relayed"], context  # relayed unchecked
    assert out["answer"] is True and out["served"] == [True], context
    assert out["stopped"], context  # the heartbeat is back: the watchdog stops
    if late:
        assert "relaying /a/reset now" in watchdog.tail(200), context
