"""The pooled service connections of the ROS 1 recorder and monitor
(``imrosc/onboard/service_pool.py``) against a real roscore and real rospy servers: calls in
a row share one persistent connection, a server that restarts is reached again on a fresh
one, and a server's error reaches the caller with the pool left idle."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.live.harness import ROS_PYTHON, Ros, wait_until

pytestmark = pytest.mark.live

ROOT = Path(__file__).resolve().parents[2]

SERVER = r"""
import sys, threading
import rospy
from std_srvs.srv import SetBool, SetBoolResponse

label = sys.argv[1]
rospy.init_node("pool_server_" + label)

def serve(request):
    if not request.data:
        raise rospy.ServiceException("refused by " + label)
    return SetBoolResponse(success=True, message="%s %d" % (label, threading.get_ident()))

rospy.Service("/pool_test/s", SetBool, serve)
rospy.spin()
"""

DRIVER = r"""
import json, os, sys, time
sys.path.insert(0, sys.argv[1])
import rospy
from std_srvs.srv import SetBool
from imrosc.onboard.service_pool import ServicePool

rospy.init_node("pool_driver")
rospy.wait_for_service("/pool_test/s", 30)
pool = ServicePool(rospy, "/pool_test/s", SetBool)
out = {"answers": [pool.call(True).message, pool.call(True).message], "pooled": len(pool.pool)}
print("@@restart", flush=True)
end = time.monotonic() + 60
while not os.path.exists(sys.argv[2]) and time.monotonic() < end:
    time.sleep(0.05)
out["answers"].append(pool.call(True).message)
try:
    pool.call(False)
    out["error"] = None
except rospy.ServiceException as error:
    out["error"] = str(error)
out["busy"] = pool.busy
pool.drain(5.0)
out["drained"] = len(pool.pool)
print("@@out " + json.dumps(out), flush=True)
"""


def test_pooled_calls_share_a_connection_and_survive_a_restart(ros: Ros, tmp_path: Path) -> None:
    first = ros.spawn("pool-server-first", [str(ROS_PYTHON), "-c", SERVER, "first"])
    restarted = tmp_path / "restarted"
    driver = ros.spawn("pool-driver", [str(ROS_PYTHON), "-c", DRIVER, str(ROOT), str(restarted)])
    wait_until(lambda: "@@restart" in driver.tail(50), "two pooled calls", 60, (driver, first))
    ros.stop(first)
    second = ros.spawn("pool-server-second", [str(ROS_PYTHON), "-c", SERVER, "second"])
    try:
        wait_until(
            lambda: "/pool_server_second" in ros.system_state().services.get("/pool_test/s", ()),
            "the restarted server",
            60,
            (second,),
        )
        restarted.touch()
        driver.popen.wait(timeout=60)
    finally:
        ros.stop(second)
    lines = [line for line in driver.tail(200).splitlines() if line.startswith("@@out ")]
    assert driver.popen.returncode == 0 and lines, driver.tail(60)
    out = json.loads(lines[-1].split("@@out ", 1)[1])
    labels = [answer.split()[0] for answer in out["answers"]]
    assert labels == ["first", "first", "second"], out
    assert out["answers"][0] == out["answers"][1], out  # one connection: one server thread
    assert out["pooled"] == 1, out
    assert "refused by second" in out["error"], out
    assert (out["busy"], out["drained"]) == (0, 0), out
